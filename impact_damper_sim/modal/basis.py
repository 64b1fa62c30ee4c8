"""Modal reduction of an assembled structure (paper section 2.2).

The massless DOFs are condensed statically first (exact for a lumped mass), then the
generalized eigenproblem ``K_sym phi = omega^2 M phi`` of the condensed system is solved with
the *symmetric* part of the stiffness. What the symmetric eigenbasis does not diagonalize is
kept as small dense modal couplings: the skew-symmetric (cross-coupled) stiffness
``Phi^T K_skew Phi`` and the physical dampers ``Phi^T C Phi``. Per-mode "tare" damping
``2 zeta omega`` is added on the diagonal.

Modes are mass-normalized (``Phi^T M Phi = I``): modal mass is 1 and the modal coordinate
``q`` has units m sqrt(kg).

The basis is a function of the matrices alone, so that a scene built twice gives the same
bits: the Lanczos start vector is fixed (``eigsh`` otherwise draws it from OS entropy), a
degenerate eigenspace gets a canonical basis (an eigensolver returns any rotation of it,
set by rounding and the start vector), and each mode's largest entry is positive.

The condensation is exact for ``K``. It is exact for ``C`` only when no dashpot touches a
massless DOF; otherwise ``[I; T]^T C [I; T]`` is the usual quasi-static approximation, and a
complete modal model no longer reproduces the physical harmonic response exactly.
"""
from __future__ import annotations

import math
import numbers
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from impact_damper_sim.fem.system import AssembledSystem, Condensation

#: Above this many master DOFs ``method='auto'`` uses shift-invert Lanczos (``eigsh``).
DENSE_LIMIT = 2000
#: A lowest eigenvalue below this fraction of ``max(K_ii/M_ii)`` counts as a rigid-body mode.
RIGID_RTOL = 1e-10
#: Relative size of off-diagonal terms below which a modal matrix counts as diagonal.
DIAGONAL_RTOL = 1e-14
#: Eigenvalues closer than this (relative) span one degenerate eigenspace (an isotropic
#: rotor's y and z modes), whose basis :func:`_canonical_basis` fixes.
DEGENERATE_RTOL = 1e-10
#: DOF amplitudes within this (relative) of the largest tie in :func:`_canonical_basis`;
#: the lowest DOF index wins, so rounding does not pick the DOF.
_TIE_RTOL = 1e-8
#: Seed of the Lanczos start vector (:func:`lanczos_start`).
_LANCZOS_SEED = 0
_METHODS = ('auto', 'dense', 'sparse')


@dataclass(frozen=True, eq=False)   # arrays inside: compare by identity
class ModalBasis:
    """Mass-normalized modal basis of a condensed structure, with its modal couplings.

    Build it with :func:`modal_reduction`. All arrays are read-only.

    Attributes
    ----------
    omega : ndarray, shape (n,)
        Undamped natural frequencies of the symmetric stiffness (rad/s), ascending.
    zeta : ndarray, shape (n,)
        Per-mode tare damping ratios (dimensionless).
    shapes : ndarray, shape (n_master, n)
        Mode shapes at the master DOFs of :attr:`condensation` (1/sqrt(kg), or
        1/(sqrt(kg) m) on rotations), ``shapes.T @ M @ shapes = I``.
    condensation : Condensation
        Static condensation the basis was built on (master/slave split, ``T``).
    selection_reason : str
        Why these modes were kept, human-readable.
    system : AssembledSystem
        The physical system the basis belongs to.
    """

    omega: np.ndarray
    zeta: np.ndarray
    shapes: np.ndarray
    condensation: Condensation
    selection_reason: str
    system: AssembledSystem
    _stiffness: np.ndarray = field(repr=False)
    _damping: np.ndarray = field(repr=False)

    @property
    def n_modes(self) -> int:
        """int: Number of retained modes."""
        return self.omega.size

    @property
    def frequencies_hz(self) -> np.ndarray:
        """ndarray: Natural frequencies (Hz)."""
        return self.omega / (2.0 * np.pi)

    def rows(self, active_indices: npt.ArrayLike) -> np.ndarray:
        """Return mode-shape values at the given active DOFs.

        Slave (massless) DOFs are recovered through the condensation, ``u_s = T u_m``. Only
        the requested rows are formed.

        Parameters
        ----------
        active_indices : int or array_like of int
            Active DOF indices (dimensionless).

        Returns
        -------
        ndarray, shape (k, n)
            ``u[active_indices] = rows @ q`` (1/sqrt(kg) on translations).
        """
        return self.condensation.recovery(active_indices) @ self.shapes

    def rows_at(self, pairs: Iterable[tuple[int, int | str]]) -> np.ndarray:
        """Return mode-shape values at DOFs named by ``(node, component)``.

        Parameters
        ----------
        pairs : sequence of (int, int or str)
            Node id and component (``0..5`` or ``'ux'`` ... ``'rz'``) of each DOF.

        Returns
        -------
        ndarray, shape (k, n)
            As :meth:`rows` (1/sqrt(kg) on translations).
        """
        return self.rows([self.system.index(node, comp) for node, comp in pairs])

    def stiffness_matrix(self) -> np.ndarray:
        """Return the modal stiffness ``diag(omega^2) + Phi^T K_skew Phi`` (1/s^2), (n, n)."""
        return self._stiffness.copy()

    def damping_matrix(self) -> np.ndarray:
        """Return the modal damping ``diag(2 zeta omega) + Phi^T C Phi`` (1/s), (n, n)."""
        return self._damping.copy()

    def coupling_is_diagonal(self) -> bool:
        """Return True if both modal matrices are diagonal to 1e-14 of their largest entry.

        Then every mode can be integrated on its own (closed-form oscillator flows).
        """
        return _is_diagonal(self._stiffness) and _is_diagonal(self._damping)

    def impulse_mobility(self, active_indices: npt.ArrayLike) -> np.ndarray:
        """Return ``R R^T``: velocity jump per unit impulse at the given DOFs (1/kg).

        Parameters
        ----------
        active_indices : int or array_like of int
            Active DOF indices where impulses act and velocities are read (dimensionless).

        Returns
        -------
        ndarray, shape (k, k)
            ``delta v = (R R^T) J`` of the retained modes (1/kg on translations).
        """
        r = self.rows(active_indices)
        return r @ r.T

    def effective_mass(self, active_indices: npt.ArrayLike) -> float | np.ndarray:
        """Return the driving-point effective mass seen by an impactor.

        Parameters
        ----------
        active_indices : int or array_like of int
            One active DOF (SDOF impactor) or two (planar impactor) (dimensionless).

        Returns
        -------
        float or ndarray
            One DOF: ``1/sum_k phi_k^2`` over the retained modes (kg). With every mode and a
            lumped mass this is the lumped mass; truncation raises it. Two DOFs: the 2x2
            mobility ``R R^T`` (1/kg), whose inverse is the effective mass matrix.
        """
        mob = self.impulse_mobility(active_indices)
        if mob.shape == (1, 1):
            if mob[0, 0] <= 0.0:
                raise ValueError('effective_mass: the retained modes do not move this DOF')
            return float(1.0 / mob[0, 0])
        if mob.shape == (2, 2):
            return mob
        raise ValueError(f'effective_mass takes one or two DOFs, got {mob.shape[0]}')


def modal_reduction(system: AssembledSystem, *, n_modes: int | None = None,
                    f_max: float | None = None, zeta: float = 0.0,
                    zeta_overrides: Mapping[int, float] | None = None,
                    method: str = 'auto') -> ModalBasis:
    """Condense and reduce ``system`` to a mass-normalized modal basis.

    Parameters
    ----------
    system : AssembledSystem
        Physical system (kg, N s/m, N/m).
    n_modes : int, optional
        Keep the lowest ``n_modes`` modes (dimensionless, >= 1).
    f_max : float, optional
        Keep every mode with frequency ``<= f_max`` (Hz, > 0). With ``n_modes`` as well, the
        smaller set is kept. With neither, all modes are kept.
    zeta : float
        Tare damping ratio of every mode (dimensionless, ``0 <= zeta < 1``).
    zeta_overrides : dict of {int: float}, optional
        Per-mode tare damping ratio by 0-based mode index (dimensionless, ``0 <= . < 1``).
    method : {'auto', 'dense', 'sparse'}
        ``'dense'``: ``scipy.linalg.eigh``; ``'sparse'``: shift-invert ``eigsh`` followed by a
        Rayleigh-Ritz step; ``'auto'``: dense up to 2000 master DOFs.

    Returns
    -------
    ModalBasis
        The retained modes and their modal couplings.

    Raises
    ------
    ValueError
        Bad selection or damping inputs (the message names the field), a stiffness that is not
        positive definite (rigid-body modes; the message gives the lowest eigenvalue), or a
        mass matrix that is not positive definite.

    Examples
    --------
    Two 1 kg masses on 1e4 N/m springs, fixed-free:

    >>> import numpy as np, scipy.sparse as sp
    >>> from impact_damper_sim.fem.system import AssembledSystem
    >>> K = sp.csr_matrix([[2e4, -1e4], [-1e4, 1e4]])
    >>> system = AssembledSystem(M=sp.identity(2, format='csr'), C=sp.csr_matrix((2, 2)),
    ...                          K=K, dofs=np.array([[1, 0], [2, 0]]))
    >>> basis = modal_reduction(system, n_modes=1, zeta=0.02)
    >>> print(basis.selection_reason)
    1 mode by count (n_modes=1); highest 9.83632 Hz
    >>> round(basis.effective_mass(1), 4)   # tip mass seen through one mode (kg)
    1.382
    """
    _check_n_modes(n_modes)
    _check_f_max(f_max)
    zeta = _check_ratio('zeta', zeta)
    if method not in _METHODS:
        raise ValueError(f'method={method!r} unknown; allowed: {_METHODS}')
    cond = system.condense()
    n_master = cond.master.size
    if n_modes is not None and n_modes > n_master:
        raise ValueError(f'n_modes={n_modes} exceeds the {n_master} modes of the condensed '
                         f'system (DOFs with mass)')
    K = 0.5 * (cond.K + cond.K.T)   # eigenproblem of the symmetric part; skew part couples
    M = cond.M
    scale = _eigen_scale(K, M)
    use_dense = method == 'dense' or (method == 'auto' and n_master <= DENSE_LIMIT)
    solver = _solve_dense if use_dense else _solve_sparse
    lam, phi = solver(K, M, n_modes, f_max, scale)
    if n_modes is not None and f_max is not None:   # both given: the smaller set
        keep = lam <= (2 * np.pi * f_max) ** 2
        lam, phi = lam[keep], phi[:, keep]
    if lam.size and lam[0] <= RIGID_RTOL * scale:
        raise ValueError(
            f'stiffness is not positive definite: lowest eigenvalue of (K_sym, M) is '
            f'{lam[0]:.6g} (rad/s)^2 (rigid-body mode or mechanism); clamp the structure')
    if lam.size == 0:
        first = solver(K, M, 1, None, scale)[0][0]
        raise ValueError(f'f_max={f_max:g} Hz is below the first natural frequency '
                         f'{np.sqrt(max(first, 0.0)) / (2 * np.pi):.6g} Hz')
    omega = np.sqrt(lam)
    reason = _reason(omega, n_modes, f_max, n_master)
    phi = _fix_signs(_canonical_basis(lam, phi))
    return _make_basis(system, cond, omega, phi, zeta, zeta_overrides, reason)


def harmonic_response(basis: ModalBasis, force_rows: npt.ArrayLike, output_rows: npt.ArrayLike,
                      Omega: npt.ArrayLike) -> npt.NDArray[np.complex128]:
    """Return the receptance of the modal model, modal couplings included.

    Parameters
    ----------
    basis : ModalBasis
        Modal model.
    force_rows : array_like, shape (k_f, n) or (n,)
        Mode-shape rows of the forced DOFs, from :meth:`ModalBasis.rows` (1/sqrt(kg)).
    output_rows : array_like, shape (k_o, n) or (n,)
        Mode-shape rows of the output DOFs (1/sqrt(kg)).
    Omega : float or array_like
        Forcing circular frequency (rad/s).

    Returns
    -------
    ndarray of complex, shape ``np.shape(Omega) + (k_o, k_f)``
        ``output_rows @ (K_m - Omega^2 I + i Omega C_m)^-1 @ force_rows.T`` (m/N).
    """
    n = basis.n_modes
    f_rows = np.atleast_2d(np.asarray(force_rows, dtype=float))
    o_rows = np.atleast_2d(np.asarray(output_rows, dtype=float))
    for name, r in (('force_rows', f_rows), ('output_rows', o_rows)):
        if r.shape[1] != n:
            raise ValueError(f'{name} has {r.shape[1]} columns, expected n_modes={n}')
    k_m = basis.stiffness_matrix()
    c_m = basis.damping_matrix()
    eye = np.eye(n)
    omegas = np.asarray(Omega, dtype=float)
    out = np.empty(omegas.shape + (o_rows.shape[0], f_rows.shape[0]), dtype=complex)
    for idx, w in np.ndenumerate(omegas):
        dyn = k_m - w * w * eye + 1j * w * c_m
        out[idx] = o_rows @ np.linalg.solve(dyn, f_rows.T)
    return out


def full_harmonic_response(system: AssembledSystem, force_index: int,
                           output_index: npt.ArrayLike,
                           Omega: npt.ArrayLike) -> complex | npt.NDArray[np.complex128]:
    """Return the receptance of the physical (uncondensed, sparse) model.

    Solves ``(K - Omega^2 M + i Omega C) u = e_force`` directly; massless DOFs need no special
    treatment because ``K`` is nonsingular.

    Parameters
    ----------
    system : AssembledSystem
        Physical system (kg, N s/m, N/m).
    force_index : int
        Active DOF index of the unit force (dimensionless).
    output_index : int or array_like of int
        Active DOF indices read out (dimensionless).
    Omega : float or array_like
        Forcing circular frequency (rad/s).

    Returns
    -------
    complex or ndarray of complex, shape ``np.shape(Omega) + np.shape(output_index)``
        Displacement per unit force (m/N).
    """
    n = system.n_dof
    force_index = int(force_index)
    if not 0 <= force_index < n:
        raise ValueError(f'force_index={force_index} out of range 0..{n - 1}')
    out_idx = np.asarray(output_index, dtype=np.int64)
    rhs = np.zeros(n, dtype=complex)
    rhs[force_index] = 1.0
    K = system.K.tocsc().astype(complex)
    M = system.M.tocsc()
    C = system.C.tocsc()
    omegas = np.asarray(Omega, dtype=float)
    out = np.empty(omegas.shape + out_idx.shape, dtype=complex)
    for idx, w in np.ndenumerate(omegas):
        dyn = (K - (w * w) * M + (1j * w) * C).tocsc()
        out[idx] = spla.spsolve(dyn, rhs)[out_idx]
    return out[()] if out.ndim == 0 else out


# --- helpers -----------------------------------------------------------------------------

def _make_basis(system: AssembledSystem, cond: Condensation, omega: np.ndarray,
                phi: np.ndarray, zeta: float, zeta_overrides: Mapping[int, float] | None,
                reason: str) -> ModalBasis:
    """Assemble a read-only :class:`ModalBasis` and its modal coupling matrices."""
    n = omega.size
    zetas = np.full(n, zeta)
    for mode, ratio in _check_overrides(zeta_overrides, n).items():
        zetas[mode] = ratio
    k_skew = 0.5 * (cond.K - cond.K.T)
    stiff = phi.T @ k_skew @ phi
    stiff[np.diag_indices(n)] = omega ** 2   # the skew part has a zero diagonal
    damp = phi.T @ cond.C @ phi
    damp[np.diag_indices(n)] += 2.0 * zetas * omega
    arrays = [omega, zetas, phi, stiff, damp]
    for a in arrays:
        a.setflags(write=False)
    return ModalBasis(omega=omega, zeta=zetas, shapes=phi, condensation=cond,
                      selection_reason=reason, system=system, _stiffness=stiff, _damping=damp)


def _solve_dense(K: np.ndarray, M: np.ndarray, n_modes: int | None, f_max: float | None,
                 scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Lowest eigenpairs with LAPACK; returns (eigenvalues (rad/s)^2, M-normalized vectors)."""
    try:
        if n_modes is not None:
            return sla.eigh(K, M, subset_by_index=[0, n_modes - 1])
        if f_max is not None:
            # (-inf, w^2] keeps any non-positive eigenvalue, so the rigid-body check still sees it
            return sla.eigh(K, M, subset_by_value=[-np.inf, (2 * np.pi * f_max) ** 2])
        return sla.eigh(K, M)
    except np.linalg.LinAlgError as exc:
        raise ValueError(f'condensed mass matrix is not positive definite ({exc}); every DOF '
                         f'kept as master must carry mass') from exc


def _solve_sparse(K: np.ndarray, M: np.ndarray, n_modes: int | None, f_max: float | None,
                  scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Lowest eigenpairs by shift-invert Lanczos, then a Rayleigh-Ritz step for exact M-norm."""
    n = K.shape[0]
    Ks = sp.csc_matrix(K)
    Ms = sp.csc_matrix(M)
    sigma = -1e-9 * scale   # just below zero: K - sigma M stays factorizable with rigid modes
    if n_modes is None and f_max is None:   # every mode: no cut-off for Lanczos to reach
        return _solve_dense(K, M, n_modes, f_max, scale)
    k = n_modes if n_modes is not None else min(n - 1, 20)
    while True:
        if k >= n - 1:
            return _solve_dense(K, M, n_modes, f_max, scale)
        vals, vecs = spla.eigsh(Ks, k=k, M=Ms, sigma=sigma, which='LM',
                                v0=lanczos_start(n))
        order = np.argsort(vals)
        vals, vecs = vals[order], vecs[:, order]
        if n_modes is not None or f_max is None or vals[-1] > (2 * np.pi * f_max) ** 2:
            break
        k = min(2 * k, n - 1)
    # Rayleigh-Ritz on the Lanczos subspace restores M-orthonormality to rounding
    lam, y = sla.eigh(vecs.T @ K @ vecs, vecs.T @ M @ vecs)
    phi = vecs @ y
    if n_modes is None and f_max is not None:
        keep = lam <= (2 * np.pi * f_max) ** 2
        lam, phi = lam[keep], phi[:, keep]
    return lam, phi


def _eigen_scale(K: np.ndarray, M: np.ndarray) -> float:
    """Return ``max(K_ii/M_ii)``, a lower bound of the largest eigenvalue ((rad/s)^2)."""
    d_m = np.diag(M)
    with np.errstate(divide='ignore', invalid='ignore'):
        ratios = np.where(d_m > 0, np.abs(np.diag(K)) / np.where(d_m > 0, d_m, 1.0), 0.0)
    return float(max(ratios.max(initial=0.0), np.finfo(float).tiny))


def lanczos_start(n: int) -> npt.NDArray[np.float64]:
    """Return the fixed start vector of every ``eigsh`` call, shape (n,).

    Without one, ``eigsh`` draws a random start (SciPy >= 1.15 from OS entropy, older
    ARPACK from a seed that advances with every call in the process), and the modes it
    returns change in their last bits from run to run, or by a rotation in a degenerate
    eigenspace. Pseudo-random, not constant: a constant vector has no component along the
    antisymmetric modes of a symmetric structure, which Lanczos would then find late.
    """
    return np.random.default_rng(_LANCZOS_SEED).uniform(-1.0, 1.0, int(n))


def _canonical_basis(lam: np.ndarray, phi: np.ndarray) -> npt.NDArray[np.float64]:
    """Give each degenerate eigenspace a basis fixed by the space, not by the solver.

    Eigenvalues within :data:`DEGENERATE_RTOL` of their neighbour form a cluster; an
    eigensolver returns any M-orthonormal basis of its span (a rotation set by rounding or
    the Lanczos start vector; for an isotropic rotor the y and z modes tilted by a random
    angle). The canonical basis is a pivoted Gram-Schmidt on the DOF amplitudes: the first
    mode is the unit vector of the span with the largest amplitude at the DOF the span moves
    most, the next is orthogonal to it with the largest amplitude at the DOF the remainder
    moves most, and so on (near ties, :data:`_TIE_RTOL`, go to the lowest DOF index). It
    depends on the span only, so it is the same for any basis the solver returned. Clusters
    of one mode are returned bit for bit; ``lam`` is ascending.
    """
    phi = np.array(phi, dtype=float)
    n = lam.size
    first = 0
    while first < n:
        last = first + 1
        while last < n and lam[last] - lam[last - 1] <= DEGENERATE_RTOL * abs(lam[last]):
            last += 1
        if last - first > 1:
            phi[:, first:last] = _canonical_span(phi[:, first:last])
        first = last
    return phi


def _canonical_span(phi: np.ndarray) -> npt.NDArray[np.float64]:
    """Canonical orthonormal basis of the span of ``phi``'s columns (see above)."""
    a = phi.T.copy()        # (m, n_dof): column j holds every mode's amplitude at DOF j
    m = a.shape[0]
    q = np.zeros((m, m))
    for k in range(m):
        norms = np.sqrt(np.einsum('ij,ij->j', a, a))
        j = int(np.flatnonzero(norms >= (1.0 - _TIE_RTOL) * norms.max())[0])
        v = a[:, j].copy()
        for _ in range(2):  # twice is enough (Kahan): orthogonal to rounding
            v -= q[:, :k] @ (q[:, :k].T @ v)
        q[:, k] = v / np.linalg.norm(v)
        a -= np.outer(q[:, k], q[:, k] @ a)
    return phi @ q


def _fix_signs(phi: np.ndarray) -> npt.NDArray[np.float64]:
    """Make each mode's largest-magnitude entry positive, so bases are reproducible."""
    phi = np.array(phi, dtype=float)
    idx = np.argmax(np.abs(phi), axis=0)
    signs = np.sign(phi[idx, np.arange(phi.shape[1])])
    signs[signs == 0] = 1.0
    return phi * signs


def _reason(omega: np.ndarray, n_modes: int | None, f_max: float | None, n_master: int) -> str:
    """Return the human-readable selection reason."""
    f_top = omega[-1] / (2 * np.pi)
    n = omega.size
    modes = 'mode' if n == 1 else 'modes'
    if n_modes is None and f_max is None:
        return f'all {n} modes (no n_modes or f_max); highest {f_top:.6g} Hz'
    if f_max is None:
        return f'{n} {modes} by count (n_modes={n_modes}); highest {f_top:.6g} Hz'
    by_f = f'all {n} {modes} with f <= {f_max:g} Hz (f_max)'
    if n_modes is None:
        return f'{by_f}; highest {f_top:.6g} Hz'
    if n < n_modes:
        return f'{by_f}, fewer than n_modes={n_modes}; highest {f_top:.6g} Hz'
    return (f'{n} {modes} by count (n_modes={n_modes}), fewer than those with f <= {f_max:g} Hz; '
            f'highest {f_top:.6g} Hz')


def _is_diagonal(a: np.ndarray) -> bool:
    """Return True if the off-diagonal of ``a`` is below 1e-14 of its largest entry."""
    scale = np.abs(a).max(initial=0.0)
    off = np.abs(a - np.diag(np.diag(a))).max(initial=0.0)
    return bool(off <= DIAGONAL_RTOL * scale)


def _check_n_modes(n_modes: object) -> None:
    """Validate ``n_modes``: None or an integer >= 1."""
    if n_modes is None:
        return
    if isinstance(n_modes, bool) or not isinstance(n_modes, numbers.Integral):
        raise ValueError(f'n_modes must be an integer >= 1, got {n_modes!r}')
    if n_modes < 1:
        raise ValueError(f'n_modes={n_modes} must be >= 1')


def _check_f_max(f_max: object) -> None:
    """Validate ``f_max``: None or a finite frequency > 0 Hz."""
    if f_max is None:
        return
    if isinstance(f_max, bool) or not isinstance(f_max, numbers.Real):
        raise ValueError(f'f_max must be a frequency in Hz, got {f_max!r}')
    if not (math.isfinite(float(f_max)) and float(f_max) > 0):
        raise ValueError(f'f_max={f_max!r} Hz must be finite and > 0')


def _check_ratio(name: str, value: object) -> float:
    """Validate a damping ratio: a real number in [0, 1). Returns it as float."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f'{name} must be a damping ratio in [0, 1), got {value!r}')
    value = float(value)
    if not 0.0 <= value < 1.0:   # also rejects NaN
        raise ValueError(f'{name}={value!r} out of range [0, 1)')
    return value


def _check_overrides(overrides: object, n: int) -> dict[int, float]:
    """Validate ``zeta_overrides`` against ``n`` retained modes; returns {int: float}."""
    if overrides is None:
        return {}
    if not hasattr(overrides, 'items'):
        raise ValueError(f'zeta_overrides must be a mapping {{mode index: ratio}}, '
                         f'got {type(overrides).__name__}')
    checked = {}
    for mode, ratio in overrides.items():
        if isinstance(mode, bool) or not isinstance(mode, numbers.Integral):
            raise ValueError(f'zeta_overrides: mode index {mode!r} is not an integer')
        if not 0 <= int(mode) < n:
            raise ValueError(f'zeta_overrides: mode index {mode} out of range 0..{n - 1} '
                             f'({n} retained modes)')
        checked[int(mode)] = _check_ratio(f'zeta_overrides[{mode}]', ratio)
    return checked


__all__ = ['ModalBasis', 'modal_reduction', 'harmonic_response', 'full_harmonic_response',
           'lanczos_start']
