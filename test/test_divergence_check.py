"""The compiled divergence checks (``kernels.divergence_check``) against their plain twins and
against the NumPy rule they replace: all finite, every displacement within its bound."""
import numpy as np
import pytest

from impact_damper_sim.integrate.kernels import divergence_check as dc

BOUND = 1.0e3


def _rule_samples(d, v, a, bound):
    # the NumPy statement of the rule (divergence.check_samples before the kernel)
    return bool((d.size == 0 or np.abs(d).max() <= bound) and np.isfinite(v).all()
                and np.isfinite(a).all())


def _cases():
    rng = np.random.default_rng(7)
    base = [rng.standard_normal((20, 6)) for _ in range(3)]
    yield base
    for field in range(3):
        for bad in (np.nan, np.inf, -np.inf, 1e308, BOUND, np.nextafter(BOUND, np.inf),
                    -np.nextafter(BOUND, np.inf), 5e-324):
            for where in ((0, 0), (19, 5), (7, 3)):
                arrays = [x.copy() for x in base]
                arrays[field][where] = bad
                yield arrays
    yield [np.zeros((0, 6))] * 3
    yield [np.zeros((4, 0))] * 3
    wide = rng.standard_normal((5, 40))
    yield [wide[:, ::2], wide[:, 1::2], wide.T.copy()]   # strided views as well as copies


@pytest.mark.parametrize('twin', [dc.samples_clean, dc.samples_clean_py])
def test_samples_clean_is_the_rule(twin):
    n = 0
    for d, v, a in _cases():
        for bound in (BOUND, np.inf, 0.0, np.nan):
            expected = _rule_samples(d, v, a, bound)
            assert twin(d, v, a, bound) is expected, (d, v, a, bound)
            n += not expected
    assert n > 50   # the cases include many unclean chunks


@pytest.mark.parametrize('twin', [dc.state_finite, dc.state_finite_py])
def test_state_finite_is_the_rule(twin):
    rng = np.random.default_rng(3)
    q, qd = rng.standard_normal(10), rng.standard_normal(10)
    assert twin(q, qd) is True
    assert twin(np.zeros(0), np.zeros(0)) is True
    assert twin(np.full(3, 1e308), q) is True
    for bad in (np.nan, np.inf, -np.inf):
        for i in (0, 9):
            for which in (0, 1):
                pair = [q.copy(), qd.copy()]
                pair[which][i] = bad
                assert twin(*pair) is False
    x = rng.standard_normal(20)
    assert twin(x[::2], x[1::2]) is True   # strided halves
