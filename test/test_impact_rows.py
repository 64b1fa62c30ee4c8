"""The compiled impact rows (``kernels.impact_rows``), its ``py_func`` and its plain twin against
the NumPy statement of the live impact batch's rows they replace, byte for byte: the impacts
among a chunk's events in stamp order (equal stamps in event order), each impulse component in
its impactor's column, the impactor in the low four bytes of the second slot."""
import numpy as np
import pytest

from impact_damper_sim.integrate.events import IMPACT, empty_events
from impact_damper_sim.integrate.kernels import impact_rows as ir


def _rows_numpy(events, start_ns, columns):
    # the NumPy statement (NodeMessages._impact_batch before the kernel)
    at = (events['kind'] == IMPACT).nonzero()[0]
    n = at.size
    if not n:
        return b''
    t_ns = np.rint(events['t'][at] * 1e9).astype(np.int64)
    order = np.argsort(t_ns, kind='stable')
    at, t_ns = at[order], t_ns[order]
    rows = np.zeros((n, 8), '<f8')
    rows[:, 0] = (t_ns - start_ns) * 1e-9
    which = events['impactor'][at].astype(np.int64)
    rows.view('<u4')[:, 2] = which
    flat, start = rows.reshape(-1), np.arange(0, 8 * n, 8)
    magnitude, normal = events['impulse'][at], events['normal']
    for k, column in enumerate(columns):
        flat[start + column[which]] = magnitude * normal[:, k][at]
    rows[:, 5] = np.abs(events['v_n'][at])
    rows[:, 6] = np.abs(events['v_n_after'][at])
    rows[:, 7] = events['loss'][at]
    return rows.tobytes()


def _rows(twin, events, start_ns, columns):
    m = events.size
    rows = np.zeros((m, 8), '<f8')
    n = twin(events['t'], events['kind'], events['impactor'], events['impulse'],
             events['normal'], events['v_n'], events['v_n_after'], events['loss'], IMPACT,
             start_ns, columns, np.empty(m, np.int64), rows, rows.view('<u4'))
    assert not rows[n:].any()   # nothing written past the impacts
    return rows[:n].tobytes()


# two impactors in a plane (ux uy; uy uz), one along ux (its second component: v_approach)
COLUMNS = np.array([[2, 3, 2], [3, 4, 5]], np.int64)


def _events(rng, m, t0=1.25):
    ev = empty_events(m)
    ev['t'] = t0 + np.sort(rng.uniform(0, 0.01, m))
    ev['kind'] = rng.choice([IMPACT, 1, 2, 3], m, p=[0.7, 0.1, 0.1, 0.1])
    ev['impactor'] = rng.integers(0, 3, m)
    angle = rng.uniform(0, 2 * np.pi, m)
    ev['normal'][:, 0], ev['normal'][:, 1] = np.cos(angle), np.sin(angle)
    ev['v_n'] = rng.normal(0, 1, m)
    ev['impulse'] = rng.exponential(1e-3, m)
    ev['loss'] = rng.exponential(1e-4, m)
    ev['v_n_after'] = rng.normal(0, 1, m)
    ev['v_h_jump'] = rng.normal(0, 1, m)
    return ev


def _cases():
    rng = np.random.default_rng(11)
    for m in (0, 1, 2, 3, 40, 200):
        yield _events(rng, m)
    ev = _events(rng, 60)
    rng.shuffle(ev)   # out of time order
    yield ev
    ev = _events(rng, 30)
    ev['t'][5:15] = ev['t'][5]   # equal stamps: event order kept
    ev['t'][20:24] = ev['t'][20] + 0.4e-9   # equal once rounded to ns
    ev['kind'][5:15] = IMPACT
    yield ev
    ev = _events(rng, 20)
    ev['kind'] = 2   # no impact at all
    yield ev
    ev = _events(rng, 20)
    ev['normal'][::3] = -0.0   # signed zeros keep their sign bit
    ev['v_n'][::4] = -0.0
    yield ev


@pytest.mark.parametrize('twin', [ir.impact_rows, ir.impact_rows.py_func, ir.impact_rows_py])
def test_impact_rows_are_the_numpy_rows_byte_for_byte(twin):
    n = 0
    for events in _cases():
        for start_ns in (1_250_000_000, int(round(events['t'].min(initial=1.25) * 1e9))):
            expected = _rows_numpy(events, start_ns, COLUMNS)
            assert _rows(twin, events, start_ns, COLUMNS) == expected
            n += len(expected) // 64
    assert n > 500   # many impacts compared


def test_a_contiguous_copy_of_the_fields_gives_the_same_rows():
    """Field views of the structured events (strided) and contiguous copies alike."""
    events = _events(np.random.default_rng(5), 50)
    columns = COLUMNS
    m = events.size
    fields = [np.ascontiguousarray(events[f]) for f in
              ('t', 'kind', 'impactor', 'impulse', 'normal', 'v_n', 'v_n_after', 'loss')]
    rows = np.zeros((m, 8))
    n = ir.impact_rows(*fields, IMPACT, 1_250_000_000, columns, np.empty(m, np.int64), rows,
                       rows.view('<u4'))
    assert rows[:n].tobytes() == _rows_numpy(events, 1_250_000_000, columns)
