"""Event records and results shared by every integrator."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

EVENT_KINDS = ('impact', 'stick', 'release', 'graze')
#: ``kind`` of an impact event (its index in :data:`EVENT_KINDS`)
IMPACT = EVENT_KINDS.index('impact')

#: One record per event. ``normal`` is the unit contact normal in the housing plane (SDOF
#: impactors use its first entry, +-1 for the wall hit); ``v_n`` the closing normal relative
#: velocity before the event (m/s); ``impulse`` the impulse magnitude (N s); ``loss`` the
#: kinetic energy dissipated (J); ``v_n_after`` the normal relative velocity just after it and
#: ``v_h_jump`` the jump of the housing's normal velocity (m/s), both measured from the
#: simulated state after the impulse was applied.
EVENT_DTYPE = np.dtype([('t', 'f8'), ('impactor', 'i8'), ('kind', 'i8'), ('normal', 'f8', (2,)),
                        ('v_n', 'f8'), ('impulse', 'f8'), ('loss', 'f8'), ('v_n_after', 'f8'),
                        ('v_h_jump', 'f8')])

# sticking rules
STICK_RULES = ('paper', 'accumulation', 'none')


def empty_events(capacity: int = 0) -> np.ndarray:
    """Return an empty event array."""
    return np.zeros(capacity, dtype=EVENT_DTYPE)


@dataclass
class Samples:
    """Sensor outputs at the end of each step.

    Attributes
    ----------
    t : ndarray, shape (k,)
        Sample times (s).
    displacement, velocity : ndarray, shape (k, n_s)
        Sensor displacement (m) and velocity (m/s).
    acceleration : ndarray, shape (k, n_s)
        Smooth (non-impulsive) acceleration at the sample instant (m/s^2). The impulsive part
        is in the velocity jumps; :meth:`mean_acceleration` includes it.
    """

    t: np.ndarray
    displacement: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


@dataclass
class EnergyLedger:
    """Energy bookkeeping (J).

    Attributes
    ----------
    structure : float
        Kinetic plus potential energy of the structure (J).
    impactors : float
        Kinetic energy of the impactors (J).
    impacts : float
        Dissipated by restitution impacts (J).
    sticking : float
        Dissipated by the plastic completion of bounce-downs (J).
    damping : float
        Dissipated by damping (J).
    forcing : float
        Work done by the forcing (J).
    circulatory : float
        Work done by the circulatory (cross-coupled) stiffness (J).
    initial : float
        Total energy at the start (J).
    """

    structure: float
    impactors: float
    impacts: float
    sticking: float
    damping: float
    forcing: float
    circulatory: float
    initial: float

    @property
    def total(self) -> float:
        """float: Structure plus impactor energy now (J)."""
        return self.structure + self.impactors

    @property
    def residual(self) -> float:
        """float: ``total - (initial + work - dissipation)`` (J); zero for an exact ledger."""
        return self.total - (self.initial + self.forcing + self.circulatory
                             - self.impacts - self.sticking - self.damping)

    @property
    def relative_residual(self) -> float:

        """float: residual over the largest energy in the ledger (dimensionless)."""
        scale = max(abs(self.initial), abs(self.total), abs(self.forcing), abs(self.damping),
                    abs(self.impacts), abs(self.circulatory), 1e-300)
        return self.residual / scale
