"""Linear stability of a modal model: state matrix, least-damped eigenvalue, onset search.

Cross-coupled stiffness (``K_yz = -K_zy = Kcc``) feeds energy into forward whirl; the model
becomes unstable when the largest real part of the state-matrix eigenvalues crosses zero. For
an isotropic Jeffcott rotor this happens exactly at ``Kcc = c omega_n``.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt
import scipy.linalg as sla


def state_matrix(K_m: npt.ArrayLike, C_m: npt.ArrayLike,
                 M_m: npt.ArrayLike | None = None) -> npt.NDArray[np.float64]:
    """Return the first-order state matrix of ``M q'' + C q' + K q = 0``.

    Parameters
    ----------
    K_m : array_like, shape (n, n)
        Modal stiffness (1/s^2 for mass-normalized modes; N/m with a physical ``M_m``).
    C_m : array_like, shape (n, n)
        Modal damping (1/s; N s/m with a physical ``M_m``).
    M_m : array_like, shape (n, n), optional
        Mass matrix (kg); identity (mass-normalized modes) when omitted.

    Returns
    -------
    ndarray, shape (2n, 2n)
        ``A`` with ``d/dt [q; q'] = A [q; q']`` (1/s in the velocity block, 1/s^2 below).
    """
    K_m = np.atleast_2d(np.asarray(K_m, dtype=float))
    C_m = np.atleast_2d(np.asarray(C_m, dtype=float))
    n = K_m.shape[0]
    if K_m.shape != (n, n) or C_m.shape != (n, n):
        raise ValueError(f'K_m {K_m.shape} and C_m {C_m.shape} must both be ({n}, {n})')
    if M_m is None:
        m_k, m_c = K_m, C_m
    else:
        M_m = np.atleast_2d(np.asarray(M_m, dtype=float))
        if M_m.shape != (n, n):
            raise ValueError(f'M_m has shape {M_m.shape}, expected ({n}, {n})')
        m_k, m_c = np.linalg.solve(M_m, K_m), np.linalg.solve(M_m, C_m)
    return np.block([[np.zeros((n, n)), np.eye(n)], [-m_k, -m_c]])


def least_damped_eigenvalue(K_m: npt.ArrayLike, C_m: npt.ArrayLike,
                            M_m: npt.ArrayLike | None = None) -> complex:
    """Return the eigenvalue of the state matrix with the largest real part.

    Parameters
    ----------
    K_m, C_m, M_m : array_like
        As for :func:`state_matrix` (1/s^2, 1/s, kg).

    Returns
    -------
    complex
        Eigenvalue (1/s); the model is asymptotically stable when its real part is < 0.
        Of a conjugate pair, the one with non-negative imaginary part is returned.
    """
    lam = sla.eigvals(state_matrix(K_m, C_m, M_m))
    top = lam.real.max()
    candidates = lam[lam.real >= top - 1e-12 * max(np.abs(lam).max(), 1.0)]
    return complex(candidates[np.argmax(candidates.imag)])


def onset_cross_coupling(build_basis_for_kcc: Callable[[float], tuple[npt.ArrayLike, ...]],
                         lo: float, hi: float, rtol: float = 1e-6,
                         max_iter: int = 200) -> float:
    """Find the cross-coupled stiffness at which the model loses stability, by bisection.

    Parameters
    ----------
    build_basis_for_kcc : callable
        ``kcc -> (K_m, C_m)`` or ``(K_m, C_m, M_m)``: the modal matrices for a cross-coupled
        stiffness ``kcc`` (N/m), e.g. from :meth:`ModalBasis.stiffness_matrix` and
        :meth:`ModalBasis.damping_matrix`.
    lo, hi : float
        Bracket (N/m); the growth rate ``max Re(lambda)`` must change sign between them.
    rtol : float
        Stop when the bracket is narrower than ``rtol * |kcc|`` (dimensionless, > 0).
    max_iter : int
        Bisection step limit (dimensionless).

    Returns
    -------
    float
        ``kcc`` at the zero crossing of ``max Re(lambda)`` (N/m).
    """
    if not rtol > 0:
        raise ValueError(f'rtol={rtol!r} must be > 0')
    lo, hi = float(lo), float(hi)
    if not lo < hi:
        raise ValueError(f'bracket lo={lo:g} N/m must be below hi={hi:g} N/m')

    def growth(kcc: float) -> float:
        return least_damped_eigenvalue(*build_basis_for_kcc(kcc)).real

    g_lo, g_hi = growth(lo), growth(hi)
    if g_lo == 0.0:
        return lo
    if g_hi == 0.0:
        return hi
    if np.sign(g_lo) == np.sign(g_hi):
        raise ValueError(f'max Re(lambda) does not change sign between lo={lo:g} N/m '
                         f'({g_lo:.3g} 1/s) and hi={hi:g} N/m ({g_hi:.3g} 1/s)')
    for _ in range(max_iter):
        mid = 0.5 * (lo + hi)
        if hi - lo <= rtol * abs(mid):
            return mid
        g_mid = growth(mid)
        if g_mid == 0.0:
            return mid
        if np.sign(g_mid) == np.sign(g_lo):
            lo, g_lo = mid, g_mid
        else:
            hi = mid
    raise ValueError(f'onset bisection did not reach rtol={rtol:g} in max_iter={max_iter} steps')


__all__ = ['least_damped_eigenvalue', 'onset_cross_coupling', 'state_matrix']
