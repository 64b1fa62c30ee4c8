"""Exact flows of the linear model in complex first-order modal form.

With ``x = [q; q']`` the model is ``x' = A x + [0; M^{-1} B] u``. Writing ``A = V Lambda V^{-1}``
and ``x = Re(V y)``, every coordinate of ``y`` obeys a scalar ODE ``y_k' = lambda_k y_k +
(W u)_k``, ``W = V^{-1} [0; M^{-1} B]``, whose solution is closed form:

* harmonic inputs ``Re(U exp(i Omega t))`` have the particular solution
  ``W U / (2 (i Omega - lambda)) exp(i Omega t)`` plus its mirror at ``-Omega``;
* sampled inputs, linear between samples (first-order hold), contribute
  ``phi_1(lambda tau) W u_0 + phi_2(lambda tau) W u'`` (Nigam & Jennings 1969).

For a diagonal modal model (``M = I``, diagonal ``C`` and ``K``) ``V`` is built in closed form,
mode by mode: ``lambda = -zeta omega +- i omega sqrt(1 - zeta^2)``, eigenvectors ``[1; lambda]``.
When a cross-coupled stiffness, physical dampers or a stuck impactor's mass couple the modes,
``V`` comes from the eigen-decomposition of ``A``, i.e. the matrix exponential
``exp(A tau) = V exp(Lambda tau) V^{-1}`` evaluated for any ``tau`` at no extra cost.

Half the state is redundant: ``A`` is real, so its complex eigenvalues come in conjugate
pairs with conjugate eigenvectors, and for a real ``x`` the two coordinates of a pair are
conjugates. Only the member with ``Im lambda > 0`` is kept, its eigenvector doubled
(``x = Re(V y)`` still holds); real eigenvalues are kept as they are. Every kernel then works
on about ``n`` coordinates instead of ``2 n``.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..dampers.law import law_mobility
from .model import LinearModel

FloatArray = npt.NDArray[np.float64]
ComplexArray = npt.NDArray[np.complex128]
#: eigenvalues, eigenvectors (columns) and their inverse
Eigensystem = tuple[ComplexArray, ComplexArray, ComplexArray]

#: Largest condition number of the eigenvector matrix accepted before refusing the flow.
MAX_EIGENVECTOR_CONDITION = 1e10


@dataclass(frozen=True)
class FlowConfig:
    """Arrays of one configuration (one set of stuck masses) for the exact kernel.

    All complex arrays act on the modal state ``y``: one coordinate per complex-conjugate
    pair of eigenvalues and one per real eigenvalue (``n2``, ``n <= n2 <= 2 n``).

    Attributes
    ----------
    lam : ndarray of complex, shape (n2,)
        Eigenvalues (1/s).
    V : ndarray of complex, shape (2 n, n2)
        Eigenvectors (of a complex pair, twice the one kept); ``[q; q'] = Re(V y)``.
    Vinv : ndarray of complex, shape (n2, 2 n)
        The rows of the kept coordinates in the inverse of the full eigenvector matrix.
    W : ndarray of complex, shape (n2, n_f)
        Input map (1/(N s) in modal units).
    sensor_q, sensor_v : ndarray of complex, shape (n_s, n2)
        Sensor displacement and velocity rows.
    house_q : ndarray of complex, shape (n_i, 2, n2)
        Housing displacement rows (second row unused for SDOF impactors); velocities and
        accelerations follow from the flow's derivatives of ``y``.
    kick : ndarray of complex, shape (n_i, 2, n2)
        Change of ``y`` per unit housing impulse on each row (1/(N s) scaled).
    mobility : ndarray, shape (n_i, 2, 2)
        Mobility each impactor's law uses (1/kg).
    house_mobility : ndarray, shape (n_i, 2, 2)
        The model's mobility ``R M^-1 R^T`` at each housing (1/kg): the housing velocity
        jumps by it times an impulse, whatever the law.
    release_map : ndarray, shape (n_i, 2, 2)
        For a stuck impactor, ``(I - m G_s)^{-1}`` with ``G_s`` its housing mobility in this
        configuration: it maps the housing acceleration to the one the housing would have
        without the impactor, whose normal component is the sign of the frictionless normal
        contact force. Identity for free impactors.
    part_plus, part_minus : ndarray of complex, shape (n_h, n2)
        Harmonic particular-solution coefficients at ``+Omega_h`` and ``-Omega_h``.
    mass : ndarray, shape (n, n)
        Mass matrix of this configuration.
    condition : float
        Condition number of ``V`` (dimensionless).
    """

    lam: np.ndarray
    V: np.ndarray
    Vinv: np.ndarray
    W: np.ndarray
    sensor_q: np.ndarray
    sensor_v: np.ndarray
    house_q: np.ndarray
    kick: np.ndarray
    mobility: np.ndarray
    house_mobility: np.ndarray
    release_map: np.ndarray
    part_plus: np.ndarray
    part_minus: np.ndarray
    mass: np.ndarray
    condition: float

    def to_state(self, q: npt.ArrayLike, qd: npt.ArrayLike) -> ComplexArray:
        """Return ``y`` for coordinates ``q`` and velocities ``qd``."""
        return self.Vinv @ np.concatenate([q, qd]).astype(complex)

    def from_state(self, y: ComplexArray) -> tuple[FloatArray, FloatArray]:
        """Return ``(q, qd)`` for the modal state ``y`` (real parts)."""
        x = (self.V @ y).real
        n = x.size // 2
        return x[:n], x[n:]


def _is_diagonal(a: np.ndarray) -> bool:
    off = a - np.diag(np.diag(a))
    return not np.any(off)


def _diagonal_eigensystem(K: FloatArray, C: FloatArray) -> Eigensystem:
    """Closed-form eigenvalues/vectors of uncoupled modes (M = I)."""
    n = K.shape[0]
    omega2 = np.diag(K).copy()
    c = np.diag(C).copy()
    if np.any(omega2 <= 0):
        raise ValueError('a mode has a non-positive stiffness: the flow needs omega > 0')
    # roots of s^2 + c s + omega^2; the discriminant decides complex or real pairs
    disc = (c * c / 4 - omega2).astype(complex)
    root = np.sqrt(disc)
    lam_p = -c / 2 + root
    lam_m = -c / 2 - root
    if np.any(np.abs(lam_p - lam_m) <= 1e-12 * np.abs(lam_p)):
        raise ValueError('a mode is critically damped (zeta = 1): its flow is defective')
    lam = np.empty(2 * n, dtype=complex)
    lam[0::2] = lam_p
    lam[1::2] = lam_m
    V = np.zeros((2 * n, 2 * n), dtype=complex)
    Vinv = np.zeros_like(V)
    idx = np.arange(n)
    V[idx, 2 * idx] = 1.0
    V[idx, 2 * idx + 1] = 1.0
    V[n + idx, 2 * idx] = lam_p
    V[n + idx, 2 * idx + 1] = lam_m
    det = lam_m - lam_p
    Vinv[2 * idx, idx] = lam_m / det
    Vinv[2 * idx, n + idx] = -1.0 / det
    Vinv[2 * idx + 1, idx] = -lam_p / det
    Vinv[2 * idx + 1, n + idx] = 1.0 / det
    return lam, V, Vinv


def _conjugate_half(lam: ComplexArray, V: ComplexArray, Vinv: ComplexArray) -> Eigensystem:
    """Keep one coordinate of each conjugate pair (see the module notes).

    Returns ``(lam, V, Vinv)`` of the kept coordinates, with the kept eigenvector of a pair
    doubled; the full system if the pairs cannot be matched (then nothing is dropped).
    """
    n2 = lam.size
    scale = np.maximum(np.abs(lam), 1e-300)
    real = np.abs(lam.imag) <= 1e-12 * scale
    keep: list[int] = []
    weight: list[float] = []
    used = np.zeros(n2, dtype=bool)
    for k in np.argsort(-lam.imag, kind='stable'):
        if used[k]:
            continue
        used[k] = True
        if real[k]:
            keep.append(k)
            weight.append(1.0)
            continue
        gaps = np.abs(lam - np.conj(lam[k]))
        gaps[used] = np.inf
        partner = int(np.argmin(gaps))
        # the partner's eigenvector is the conjugate (np.allclose costs 10 x this test)
        matched = gaps[partner] <= 1e-12 * scale[k] and (
            np.abs(V[:, partner] - np.conj(V[:, k])).max() <= 1e-12 * np.abs(V[:, k]).max())
        if not matched:
            return lam, V, Vinv
        used[partner] = True
        keep.append(k)
        weight.append(2.0)
    kept = np.array(keep)
    return lam[kept], V[:, kept] * np.array(weight), Vinv[kept]


def _general_eigensystem(M: FloatArray, C: FloatArray, K: FloatArray) -> Eigensystem:
    n = K.shape[0]
    Minv_K = np.linalg.solve(M, K)
    Minv_C = np.linalg.solve(M, C)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv_K, -Minv_C]])
    lam, V = np.linalg.eig(A)
    V = V.astype(complex)
    Vinv = np.linalg.inv(V)
    return lam.astype(complex), V, Vinv


def build_flow(model: LinearModel, stuck_masses: Sequence[float] | np.ndarray,
               omegas: npt.ArrayLike, amplitudes: npt.ArrayLike, law: str = 'effective_mass',
               carried_masses: Sequence[float] | np.ndarray | None = None,
               release_masses: Sequence[float] | np.ndarray | None = None) -> FlowConfig:
    """Build the exact-flow arrays for one configuration.

    Parameters
    ----------
    model : LinearModel
        The model (coordinates, matrices, sensors, impactors).
    stuck_masses : sequence of float
        Mass riding each impactor's housing (kg), 0 for a free impactor.
    omegas : ndarray, shape (n_h,)
        Harmonic forcing frequencies (rad/s).
    amplitudes : ndarray of complex, shape (n_h, n_f)
        Harmonic forcing amplitudes (N), see ``Forcing.harmonic_table``.
    law : {'effective_mass', 'lumped_mass'}
        Impact law that sizes the impulses.
    carried_masses : sequence of float, optional
        Mass of each stuck impactor that the model's coordinates already hold (kg), e.g. a
        basis computed with it; used, like ``stuck_masses``, for the release map only.
    release_masses : sequence of float, optional
        Mass (kg) to build every impactor's release map with, stuck or not in this
        configuration (a table of configurations shared by several stuck sets needs them
        all); default: the riding masses above.

    Returns
    -------
    FlowConfig
        Arrays for the exact kernel.
    """
    n = model.n
    M = model.stuck_mass_matrix(stuck_masses)
    if (not any(stuck_masses) and np.array_equal(M, np.eye(n))
            and _is_diagonal(model.C) and _is_diagonal(model.K)):
        lam, V, Vinv = _diagonal_eigensystem(model.K, model.C)
        condition = float(np.linalg.cond(V))
    else:
        lam, V, Vinv = _general_eigensystem(M, model.C, model.K)
        condition = float(np.linalg.cond(V))
    if not np.isfinite(condition) or condition > MAX_EIGENVECTOR_CONDITION:
        raise ValueError(f'the state matrix is (nearly) defective: cond(V) = {condition:.3g}; '
                         'exact flows need a diagonalizable model (check zeta = 1 or '
                         'repeated coupled modes)')
    lam, V, Vinv = _conjugate_half(lam, V, Vinv)
    Vq, Vv = V[:n], V[n:]
    MinvB = np.linalg.solve(M, model.B)
    W = Vinv[:, n:] @ MinvB.astype(complex)
    sensor_q = model.sensors @ Vq
    sensor_v = model.sensors @ Vv
    n_i = len(model.impactors)
    house_q = np.zeros((n_i, 2, lam.size), dtype=complex)
    kick = np.zeros_like(house_q)
    mobility = np.zeros((n_i, 2, 2))
    house_mobility = np.zeros((n_i, 2, 2))
    release_map = np.tile(np.eye(2), (n_i, 1, 1))
    # impactors in one housing share its rows: the same products
    site_terms: dict[tuple[object, ...], tuple[ComplexArray, ComplexArray, FloatArray]] = {}
    release_terms: dict[tuple[object, ...], FloatArray] = {}
    for j, imp in enumerate(model.impactors):
        d = imp.dim
        R = imp.rows
        key = (R.shape, R.tobytes())
        if key not in site_terms:
            MinvRt = np.linalg.solve(M, R.T)
            site_terms[key] = (R @ Vq, (Vinv[:, n:] @ MinvRt).T, R @ MinvRt)
        house_q[j, :d], kick[j, :d], RMR = site_terms[key]
        house_mobility[j, :d, :d] = RMR
        mobility[j, :d, :d] = law_mobility(RMR, imp.housing_mass, law)
        riding = stuck_masses[j] or (carried_masses[j] if carried_masses is not None else 0.0)
        if release_masses is not None:
            riding = release_masses[j]
        if riding:
            if (key, riding) not in release_terms:
                release_terms[key, riding] = np.linalg.inv(np.eye(d) - riding * RMR)
            release_map[j, :d, :d] = release_terms[key, riding]

    omegas = np.asarray(omegas, dtype=float)
    amplitudes = np.asarray(amplitudes, dtype=complex).reshape(omegas.size, model.n_inputs)
    part_plus = np.zeros((omegas.size, lam.size), dtype=complex)
    part_minus = np.zeros_like(part_plus)
    for h, (om, U) in enumerate(zip(omegas, amplitudes)):
        denom_p = 1j * om - lam
        denom_m = -1j * om - lam
        if np.any(np.abs(denom_p) < 1e-12 * max(om, 1.0)) or \
                np.any(np.abs(denom_m) < 1e-12 * max(om, 1.0)):
            raise ValueError(f'harmonic forcing at {om} rad/s hits an undamped eigenvalue '
                             '(exact resonance): add damping or detune')
        part_plus[h] = (W @ U) / (2 * denom_p)
        part_minus[h] = (W @ U.conj()) / (2 * denom_m)
    return FlowConfig(lam, V, Vinv, W, sensor_q, sensor_v, house_q, kick, mobility,
                      house_mobility, release_map, part_plus, part_minus, M, condition)
