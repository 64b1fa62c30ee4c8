"""Impact laws: instantaneous impulses that obey restitution and conserve momentum.

Sign convention. ``n`` is the unit contact normal in the housing plane, pointing from the
cavity centre to the wall that is hit. ``v_n = n . (v_i - v_h)`` is the normal relative
velocity, positive when closing. The wall gives the impactor the impulse ``-J n`` and the
housing ``+J n`` (J >= 0, N s).

In the model actually simulated, a housing impulse ``P`` (N s, one entry per housing row)
changes the coordinate velocities by ``M^{-1} R^T P``, so the housing velocity changes by
``G P`` with the *mobility* ``G = R M^{-1} R^T`` (1/kg). For one row of a mass-normalized
modal model ``G = sum_k phi_k^2``, the inverse of the driving-point effective mass.

* Effective-mass law (default): ``J = (1 + e) v_n / (1/m + n^T G n)``. Then the normal
  relative velocity after impact is exactly ``-e v_n``, the momentum of impactor plus model
  is conserved, and the energy lost is ``0.5 (1 - e^2) v_n^2 / (1/m + n^T G n)``.
* Lumped-mass law (the paper's): ``G`` is replaced by ``I / m_h`` with ``m_h`` the lumped
  housing mass. It is exact only when every mode is retained; with truncated modes the
  simulated restitution and momentum are off, which ``study`` can quantify. The energy
  ledger books what the simulated model loses, ``J v_n - J^2 (1/m + n^T G n) / 2`` with the
  model's ``G``, not the law's own ``0.5 (1 - e^2) v_n^2 / (1/m + 1/m_h)`` (issue 26: the two
  differed by 13 % on rbs_kcc and the energy balance did not close).
* Lock (stuck entry): a plastic impulse that cancels the whole relative velocity,
  ``P = (I/m + G)^{-1} v_rel``; loss ``0.5 v_rel^T (I/m + G)^{-1} v_rel`` with the
  effective-mass law (the lumped-mass law's loss, as booked: ``integrate/kernels/contact.py``,
  ``impact``).
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt

EFFECTIVE_MASS = 'effective_mass'
LUMPED_MASS = 'lumped_mass'
IMPACT_LAWS = (EFFECTIVE_MASS, LUMPED_MASS)


def law_mobility(mobility: npt.ArrayLike, housing_mass: float, law: str) -> np.ndarray:
    """Return the mobility matrix the chosen impact law uses (1/kg).

    Parameters
    ----------
    mobility : ndarray, shape (d, d)
        Model mobility ``R M^{-1} R^T`` at the housing (1/kg).
    housing_mass : float
        Lumped housing mass (kg); required (> 0) by the lumped-mass law.
    law : {'effective_mass', 'lumped_mass'}
        Impact law.

    Returns
    -------
    ndarray, shape (d, d)
        Mobility used to size impulses (1/kg).
    """
    if law == EFFECTIVE_MASS:
        return np.asarray(mobility, dtype=float)
    if law == LUMPED_MASS:
        if not housing_mass > 0:
            raise ValueError('the lumped-mass impact law needs housing_mass > 0 kg')
        return np.eye(np.shape(mobility)[0]) / housing_mass
    raise ValueError(f'impact law must be one of {IMPACT_LAWS}, got {law!r}')


def normal_impulse(v_n: float, mass: float, mobility_nn: float, cor: float) -> float:
    """Impulse magnitude of a restitution impact (N s).

    Parameters
    ----------
    v_n : float
        Closing normal relative velocity (m/s), > 0 for an impact.
    mass : float
        Impactor mass (kg).
    mobility_nn : float
        ``n^T G n`` (1/kg).
    cor : float
        Coefficient of restitution (dimensionless).

    Returns
    -------
    float
        ``J = (1 + e) v_n / (1/m + n^T G n)`` (N s).
    """
    return (1.0 + cor) * v_n / (1.0 / mass + mobility_nn)


def normal_impact_loss(v_n: float, mass: float, mobility_nn: float, cor: float) -> float:
    """Energy lost in a restitution impact (J): ``0.5 (1 - e^2) v_n^2 / (1/m + n^T G n)``."""
    return 0.5 * (1.0 - cor * cor) * v_n * v_n / (1.0 / mass + mobility_nn)


def lock_impulse(v_rel: np.ndarray, mass: float, mobility: np.ndarray) -> np.ndarray:
    """Housing impulse vector that makes the relative velocity vanish (N s).

    Parameters
    ----------
    v_rel : ndarray, shape (d,)
        Relative velocity ``v_i - v_h`` (m/s).
    mass : float
        Impactor mass (kg).
    mobility : ndarray, shape (d, d)
        Mobility used by the law (1/kg).

    Returns
    -------
    ndarray, shape (d,)
        ``P = (I/m + G)^{-1} v_rel`` (N s); the impactor receives ``-P``.
    """
    v_rel = np.atleast_1d(np.asarray(v_rel, dtype=float))
    return np.linalg.solve(np.eye(v_rel.size) / mass + mobility, v_rel)


def apply_normal_impact(v_i: np.ndarray, v_h: np.ndarray, normal: np.ndarray, mass: float,
                        mobility: np.ndarray,
                        cor: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Post-impact impactor and housing velocities for a lone two-body check.

    This is the law evaluated on velocities only (no model): useful to check restitution
    and momentum in closed form. Simulators apply the same impulse through their model.

    Parameters
    ----------
    v_i, v_h : ndarray, shape (d,)
        Impactor and housing velocities before impact (m/s).
    normal : ndarray, shape (d,)
        Unit contact normal (dimensionless).
    mass : float
        Impactor mass (kg).
    mobility : ndarray, shape (d, d)
        Housing mobility (1/kg).
    cor : float
        Coefficient of restitution (dimensionless).

    Returns
    -------
    v_i_plus, v_h_plus, impulse : ndarray, ndarray, float
        Velocities after impact (m/s) and impulse magnitude (N s).
    """
    normal = np.asarray(normal, dtype=float)
    v_n = float(normal @ (np.asarray(v_i) - np.asarray(v_h)))
    j = normal_impulse(v_n, mass, float(normal @ mobility @ normal), cor)
    return v_i - j * normal / mass, v_h + mobility @ (j * normal), j
