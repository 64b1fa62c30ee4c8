"""Numba kernels on polynomials: safe steps, Bernstein range bounds and first roots.

A polynomial is an array of normalized Taylor coefficients ``a[m]``, ``p(s) = sum a[m] s^m``
(float64). Conventions as in :mod:`.flow_eval`.
"""
from __future__ import annotations

import numpy as np

from . import kernel

#: 1/6 rounded up: the cubic term of a lower bound may only grow by rounding
_SIXTH_UP = np.nextafter(1.0 / 6.0, 1.0)


def cubic_safe_step_py(g0, g1, g2, g3max, T, s_exact):
    """Largest ``s <= T`` with ``p(s) = g0 + g1 s + g2 s^2/2 - g3max s^3/6 > 0`` on ``[0, s)``.

    ``p`` is a lower bound of ``g`` when ``g3max`` bounds the third derivative of ``g``.
    Returns ``T`` when ``p`` stays positive over the whole interval. The search splits
    ``[0, T]`` at the roots of ``dp/ds`` so that every piece is monotone, then bisects in the
    first piece that ends at or below zero, returning its last point known to be positive,
    within 0.1 % of the root. A root that lies wholly below ``s_exact`` (s) is not bisected:
    the start of its piece, also safe, is returned (the event search only needs to know that
    such a function comes near zero; the bisection's chain of dependent operations was its
    hottest loop).
    """
    if g0 <= 0.0:
        return 0.0
    # each term at its least over [0, T]: a bound positive at T by more than its rounding
    # (relative to the terms' sizes) clears the whole interval (the common case) without the
    # square root and divisions below
    drop = T * (-min(g1, 0.0) + T * (-0.5 * min(g2, 0.0) + T * g3max * _SIXTH_UP))
    if g0 - drop > 1e-12 * (g0 + drop):
        return T
    # the cut points, ascending: at most two roots of dp/ds inside, then T; scalars, not an
    # array, since this runs once per impactor per search and must not allocate
    n_cut = 0
    cut0 = T
    cut1 = T
    a2 = -0.5 * g3max  # dp/ds = g1 + g2 s + a2 s^2
    if g1 <= 0.0 and g2 <= 0.0:
        pass  # dp/ds <= 0 for s >= 0 (g3max >= 0): one monotone piece, no cut to look for
    elif a2 != 0.0:
        disc = g2 * g2 - 4.0 * a2 * g1
        if disc >= 0.0:
            r = np.sqrt(disc)
            s1 = (-g2 + r) / (2.0 * a2)
            s2 = (-g2 - r) / (2.0 * a2)
            if s1 > s2:
                s1, s2 = s2, s1
            if 0.0 < s1 < T:
                cut0 = s1
                n_cut = 1
            if 0.0 < s2 < T:
                if n_cut == 0:
                    cut0 = s2
                else:
                    cut1 = s2
                n_cut += 1
    elif g2 != 0.0:
        s1 = -g1 / g2
        if 0.0 < s1 < T:
            cut0 = s1
            n_cut = 1
    half_g2 = 0.5 * g2
    sixth_g3 = g3max / 6.0
    lo = 0.0
    for i in range(n_cut + 1):
        hi = cut0 if i == 0 else (cut1 if i == 1 else T)
        if g0 + hi * (g1 + hi * (half_g2 - hi * sixth_g3)) <= 0.0:
            if hi <= s_exact:
                return lo
            for _ in range(80):
                mid = 0.5 * (lo + hi)
                if g0 + mid * (g1 + mid * (half_g2 - mid * sixth_g3)) > 0.0:
                    lo = mid
                else:
                    hi = mid
                if hi - lo <= 1e-3 * hi:
                    break
            return lo
        lo = hi
    return T


cubic_safe_step = kernel(forceinline=True)(cubic_safe_step_py)


def quadratic_first_root_py(g0, g1, g2, leaving):
    """First positive root (s) of the quadratic model ``g0 + g1 s + g2 s^2/2`` of a function
    from its value, slope and curvature at ``s = 0``; ``inf`` when the model has none.

    With ``leaving`` the function starts on zero and rises (``g0`` is ignored): the root of
    ``g(s)/s``, ``g1 + g2 s/2``. Each case in the form that cancels nothing (``g0 > 0``).
    An estimate, not a bound: the event search orders its candidates by it.
    """
    if leaving:
        return -2.0 * g1 / g2 if g2 < 0.0 else np.inf
    disc = g1 * g1 - 2.0 * g2 * g0
    if disc < 0.0:
        return np.inf
    if g1 <= 0.0:   # approaching: the smaller root
        den = np.sqrt(disc) - g1
        return 2.0 * g0 / den if den > 0.0 else np.inf
    # receding: a root only when the curvature turns it back
    return -(g1 + np.sqrt(disc)) / g2 if g2 < 0.0 else np.inf


quadratic_first_root = kernel(forceinline=True)(quadratic_first_root_py)


def _binomials(n_max):
    table = np.zeros((n_max + 1, n_max + 1))
    for n in range(n_max + 1):
        table[n, 0] = 1.0
        for k in range(1, n + 1):
            table[n, k] = table[n - 1, k - 1] + (table[n - 1, k] if k < n else 0.0)
    return table


#: Binomial coefficients C(n, k) for n <= MAX_DEGREE (read-only; a constant to Numba).
MAX_DEGREE = 24
BINOM = _binomials(MAX_DEGREE)
#: ``C(k, i)/C(n, i)``, the weights of the power-to-Bernstein conversion, at ``[n, k, i]``:
#: the same quotients the conversion would divide out, so its results stay bit for bit the
#: same without its 36 divisions (degree 7), which were its cost
BERNSTEIN_WEIGHTS = np.zeros((MAX_DEGREE + 1, MAX_DEGREE + 1, MAX_DEGREE + 1))
for _n in range(MAX_DEGREE + 1):
    for _k in range(_n + 1):
        BERNSTEIN_WEIGHTS[_n, _k, :_k + 1] = BINOM[_k, :_k + 1] / BINOM[_n, :_k + 1]
del _n, _k


def horner_py(a, n, s):
    """``p(s)`` for the degree-``n`` polynomial ``a``."""
    acc = a[n]
    for m in range(n - 1, -1, -1):
        acc = acc * s + a[m]
    return acc


horner = kernel(forceinline=True)(horner_py)


def horner_d_py(a, n, s):
    """``(p(s), p'(s))`` for the degree-``n`` polynomial ``a``."""
    p = a[n]
    d = 0.0
    for m in range(n - 1, -1, -1):
        d = d * s + p
        p = p * s + a[m]
    return p, d


horner_d = kernel(forceinline=True)(horner_d_py)


def bernstein_range_py(a, n, lo, hi, work):
    """Smallest and largest Bernstein coefficient of ``p`` on ``[lo, hi]``.

    ``p`` takes its values on ``[lo, hi]`` between them (the convex-hull property), and they
    converge to ``p``'s range as the interval shrinks. ``work`` needs ``n + 1`` entries.
    Cost ``O(n^2)``.
    """
    for m in range(n + 1):
        work[m] = a[m]
    if lo != 0.0:
        # Taylor shift p(lo + t) by repeated synthetic division
        for i in range(n):
            for m in range(n - 1, i - 1, -1):
                work[m] += lo * work[m + 1]
    w = hi - lo
    scale = 1.0
    for m in range(n + 1):
        work[m] *= scale
        scale *= w
    b_min = np.inf
    b_max = -np.inf
    for k in range(n + 1):
        b = 0.0
        for i in range(k + 1):
            b += BERNSTEIN_WEIGHTS[n, k, i] * work[i]
        b_min = min(b_min, b)
        b_max = max(b_max, b)
    return b_min, b_max


bernstein_range = kernel()(bernstein_range_py)


def newton_bracket_py(a, n, lo, hi, tol):
    """Root of ``p`` in ``[lo, hi]`` with ``p(lo) > 0 >= p(hi)``: Newton safeguarded by bisection.

    Starts from the chord's root and stops when the step or the bracket is below ``tol`` or
    when ``|p|`` is below its rounding error (``4 n eps sum |a_m s^m|``): there the sign of
    ``p`` is noise and further steps would only wander inside the noise band.
    """
    p_lo = horner(a, n, lo)
    p_hi = horner(a, n, hi)
    s = lo + (hi - lo) * (p_lo / (p_lo - p_hi)) if p_lo - p_hi > 0.0 else 0.5 * (lo + hi)
    if not (lo < s < hi):
        s = 0.5 * (lo + hi)
    for _ in range(100):
        # p, p' and the scale of p's rounding error in one pass: three independent chains
        p = a[n]
        d = 0.0
        size = abs(a[n])
        s_abs = abs(s)
        for m in range(n - 1, -1, -1):
            d = d * s + p
            p = p * s + a[m]
            size = size * s_abs + abs(a[m])
        if p > 0.0:
            lo = s
        else:
            hi = s
        if d < 0.0:
            s_new = s - p / d
        else:
            s_new = 0.5 * (lo + hi)
        if not (lo < s_new < hi):
            s_new = 0.5 * (lo + hi)
        if abs(s_new - s) <= tol or hi - lo <= tol:
            return s_new
        if abs(p) <= 4.0 * n * 2.220446049250313e-16 * size:
            return s
        s = s_new
    return s


newton_bracket = kernel()(newton_bracket_py)

#: Outcomes of :func:`certified_first_root`.
ROOT_NONE = 0
ROOT_FOUND = 1
ROOT_UNDECIDED = 2


def positive_until_py(a, n, K, s_end, work):
    """True if ``g > 0`` on ``[0, s_end]`` (s) is certified for every ``g`` with
    ``|g(s) - p(s)| <= K s^(n+1)``, ``p`` the degree-``n`` polynomial ``a``: the Bernstein
    coefficients of the lower bound ``p - K s^(n+1)`` are all positive there, or, first and
    cheaper, its terms each at their least there. ``work`` needs ``2 n + 4`` entries; its first
    ``n + 2`` hold that lower bound afterwards."""
    m = n + 1
    for i in range(n + 1):
        work[i] = a[i]
    work[m] = -K
    drop = K
    for i in range(n, 0, -1):
        drop = drop * s_end - min(a[i], 0.0)
    drop *= s_end
    if a[0] - drop > 1e-12 * (abs(a[0]) + drop):
        return True
    b_min, _ = bernstein_range(work[:m + 1], m, 0.0, s_end, work[m + 1:2 * m + 2])
    return b_min > 0.0


positive_until = kernel()(positive_until_py)


def certified_first_root_py(a, n, K, Kd, S, s_start, work, out):
    """First root on ``(0, S]`` of a function known by its Taylor polynomial and remainder.

    The function ``g`` satisfies ``|g(s) - p(s)| <= K s^(n+1)`` and
    ``|g'(s) - p'(s)| <= Kd s^n`` on ``[0, S]`` (s), with ``p`` the degree-``n`` polynomial
    ``a``; ``g > 0`` on ``[0, s_start)`` is known. Returns

    * ``ROOT_NONE``: ``g > 0`` on ``[0, S]`` (the lower bound ``p - K s^(n+1)`` is positive);
    * ``ROOT_FOUND``: ``g > 0`` on ``[0, out[0]]`` and ``g`` has exactly one root in
      ``[out[0], out[1]]``, where it is strictly decreasing; ``out[2]`` is the root of ``p``
      there (the starting point for refining on ``g`` itself);
    * ``ROOT_UNDECIDED``: none of these could be certified (a near-graze, several roots close
      together or a remainder too large): the caller must decide another way.

    Each certificate is a Bernstein range bound, so the answer is rigorous for any ``g``
    within the stated remainders. ``work`` needs ``3 n + 5`` entries.
    """
    m = n + 1
    low = work[:m + 1]
    scratch = work[m + 1:2 * m + 2]
    if positive_until(a, n, K, S, work):
        return ROOT_NONE
    # the root of the Taylor polynomial, bracketed from the last point known to be positive
    lo = min(max(s_start, 0.0), S)
    if horner(a, n, lo) <= 0.0:
        lo = 0.0
        if a[0] <= 0.0:
            return ROOT_UNDECIDED
    if horner(a, n, S) > 0.0:
        return ROOT_UNDECIDED
    r = newton_bracket(a, n, lo, S, 1e-15 * S)
    _, slope = horner_d(a, n, r)
    if not slope < 0.0:
        return ROOT_UNDECIDED
    eta = 2.0 * K * r ** m / (-slope) + 4e-16 * S
    deriv = scratch  # reuse: p' coefficients, degree n - 1
    for _attempt in range(2):
        s_a = max(r - eta, 0.0)
        s_b = min(r + eta, S)
        if s_a == 0.0:
            ok = a[0] > 0.0
        else:
            ok = bernstein_range(low, m, 0.0, s_a, scratch)[0] > 0.0
        ok = ok and horner(a, n, s_b) + K * s_b ** m < 0.0
        if ok:
            for i in range(n):
                deriv[i] = (i + 1) * a[i + 1]
            d_max = bernstein_range(deriv, n - 1, s_a, s_b, work[2 * m + 2:3 * m + 2])[1] \
                if n >= 1 else 0.0
            if d_max + Kd * s_b ** n < 0.0:
                out[0] = s_a
                out[1] = s_b
                out[2] = r
                return ROOT_FOUND
        eta *= 64.0
    return ROOT_UNDECIDED


certified_first_root = kernel()(certified_first_root_py)
