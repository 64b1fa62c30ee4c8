"""Bookkeeping every integrator shares: impactor states and the energy ledger.

An integrator keeps, per impactor ``j``: ``_stuck[j]`` (1 while it rides its housing),
``_imp_z``/``_imp_v`` (absolute position and velocity in free flight, m and m/s),
``_imp_rel`` (position relative to the housing while stuck, m) and ``_imp_mass`` (kg); and
``_ledger`` (dissipated by impacts, by sticking, by damping; work of forcing and of the
circulatory stiffness, J) with ``_initial_energy`` (J). It provides ``state()``,
``_housing_rows()`` and ``_structure_energy(q, qd)``.
"""
from __future__ import annotations

import numpy as np

from .events import EnergyLedger

#: Half-travel given to disabled impactors (m): larger than any structural motion, so they
#: fly free and never reach a wall (1e6 m also keeps the planar gap ``L^2 - r^2`` well scaled).
DISABLED_LIMIT = 1.0e6


class IntegratorBase:
    """Impactor states and energy ledger from an integrator's own state (see module doc)."""

    impacts_enabled = True

    def _release_now(self, j):
        """Release stuck impactor ``j`` at the current time with its housing's velocity."""
        raise NotImplementedError

    def set_impacts_enabled(self, enabled):
        """Switch the impact dampers on or off during a run.

        Off: stuck impactors are released with their housing's velocity and every impactor
        flies free without walls (it no longer acts on the structure; its mass stays off the
        structure, as in a free flight). On: each impactor is put back at its housing centre,
        moving with the housing, and impacts resume. Both switches change no structural
        state, so the response is continuous. The impactors' kinetic-energy change when they
        are put back is added to the ledger's ``initial`` energy (it is not physics).

        Parameters
        ----------
        enabled : bool
            True to enable impacts (dimensionless).
        """
        enabled = bool(enabled)
        if enabled == self.impacts_enabled:
            return
        if not enabled:
            for j in np.flatnonzero(self._stuck):
                self._release_now(int(j))
            self._limits_enabled = self._imp_limit.copy()
            self._imp_limit[:] = DISABLED_LIMIT
        else:
            before = self._energy_now()[1]
            q, qd = self.state()
            for j, R in enumerate(self._housing_rows()):
                d = R.shape[0]
                self._imp_z[j, :d] = R @ q
                self._imp_v[j, :d] = R @ qd
            self._imp_last_t[:] = -np.inf
            self._imp_limit[:] = self._limits_enabled
            # putting the impactors back is not physics: book its kinetic-energy change as
            # a new reference so that the ledger keeps balancing
            self._initial_energy += self._energy_now()[1] - before
        self.impacts_enabled = enabled

    def _housing_rows(self):
        """Housing rows of each impactor in the current coordinates (list of arrays)."""
        raise NotImplementedError

    def _structure_energy(self, q, qd):
        """Kinetic plus potential energy of the structure alone (J)."""
        raise NotImplementedError

    def impactor_states(self):
        """Return relative positions (m), absolute velocities (m/s) and stuck flags.

        Returns
        -------
        rel : ndarray, shape (n_i, 2)
            ``z - x_h`` (m); SDOF impactors use column 0.
        vel : ndarray, shape (n_i, 2)
            Absolute impactor velocity (m/s).
        stuck : ndarray of bool, shape (n_i,)
            True while the impactor rides its housing.
        """
        q, qd = self.state()
        rows = self._housing_rows()
        rel = np.zeros((len(rows), 2))
        vel = np.zeros((len(rows), 2))
        for j, R in enumerate(rows):
            d = R.shape[0]
            if self._stuck[j]:
                rel[j, :d] = self._imp_rel[j, :d]
                vel[j, :d] = R @ qd
            else:
                rel[j, :d] = self._imp_z[j, :d] - R @ q
                vel[j, :d] = self._imp_v[j, :d]
        return rel, vel, self._stuck.astype(bool)

    def _energy_now(self):
        q, qd = self.state()
        _, vel, _ = self.impactor_states()
        impactors = 0.5 * float(np.sum(self._imp_mass * np.sum(vel * vel, axis=1)))
        return self._structure_energy(q, qd), impactors

    def energy(self):
        """Return the :class:`~.events.EnergyLedger` now (J)."""
        structure, impactors = self._energy_now()
        led = self._ledger
        return EnergyLedger(structure, impactors, led[0], led[1], led[2], led[3], led[4],
                            self._initial_energy)
