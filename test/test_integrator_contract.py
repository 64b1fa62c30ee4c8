"""The integrator contract (:class:`~impact_damper_sim.integrate.base.IntegratorBase`): a
subclass that misses a required method fails at once, by name; every shipped integrator
calls the base ``__init__``, carries the shared attributes and keeps the interface the
simulation relies on."""
import inspect

import numpy as np
import pytest

from exact_cases import sdof_model
from impact_damper_sim.integrate.base import IntegratorBase
from impact_damper_sim.integrate.events import EVENT_DTYPE, Samples
from impact_damper_sim.integrate.forcing import Forcing
from impact_damper_sim.integrate.simulation import METHODS
from impact_damper_sim.scene.build import load

REQUIRED = {'state', 'advance', 'take_events', '_housing_rows', '_structure_energy',
            '_release_now'}
#: What the base ``__init__`` sets and callers read.
SHARED = ('model', 'forcing', 'dt', 'law', 'stick_rule', 'max_events_per_step', 'ledger_on',
          't', 'stick_time', '_imp_dim', '_imp_mass', '_imp_cor', '_imp_limit', '_stuck',
          '_imp_z', '_imp_v', '_imp_rel', '_imp_normal', '_imp_last_t', '_ledger',
          '_initial_energy', '_events', 'max_impacts_per_step', 'grazing_undecided',
          'impacts_enabled', 'n_config_changes')
#: Shipped integrators: every method, and the exact one with the paper's second basis.
CASES = [(m, {}) for m in METHODS] + [('exact', {'stuck_model': 'basis_switch'})]


class _FreeMass(IntegratorBase):
    """A minimal complete integrator: one undamped mode at rest, no impactors."""

    def __init__(self, model, forcing, dt):
        super().__init__(model, forcing, dt, law='effective_mass', stick_rule='paper',
                         stick_fraction=0.002, max_events_per_step=64, ledger=True, t0=0.0)
        self.stick_time = 1.0
        self._q = np.zeros(model.n)
        self._start_ledger()

    def state(self):
        return self._q.copy(), self._q.copy()

    def advance(self, n_steps):
        t = self.t + self.dt * np.arange(1, n_steps + 1)
        self.t = float(t[-1]) if n_steps else self.t
        zeros = np.zeros((n_steps, 1))
        return Samples(t, zeros, zeros, zeros)

    def take_events(self):
        return np.zeros(0, dtype=EVENT_DTYPE)

    def _housing_rows(self):
        return []

    def _structure_energy(self, q, qd):
        return 0.0

    def _release_now(self, j):
        raise AssertionError('no impactors')


def test_the_base_declares_what_a_subclass_must_implement():
    assert IntegratorBase.__abstractmethods__ == REQUIRED
    with pytest.raises(TypeError, match='abstract'):
        IntegratorBase(sdof_model(), Forcing(1), 1e-3, law='effective_mass',
                       stick_rule='paper', stick_fraction=0.002, max_events_per_step=64,
                       ledger=True, t0=0.0)


@pytest.mark.parametrize('missing', sorted(REQUIRED))
def test_a_subclass_missing_a_required_method_fails_by_name(missing):
    incomplete = type('Incomplete', (_FreeMass,), {missing: IntegratorBase.__dict__[missing]})
    assert inspect.isabstract(incomplete)
    with pytest.raises(TypeError, match=f"abstract method.*'?{missing}'?"):
        incomplete(sdof_model(), Forcing(1), 1e-3)


def test_a_minimal_complete_subclass_gets_the_shared_behaviour():
    sub = _FreeMass(sdof_model(), Forcing(1), 1e-3)
    assert sub.advance(5).t.size == 5 and sub.t == pytest.approx(5e-3, rel=1e-15)
    assert sub.n_config_changes == 0 and sub.impacts_enabled
    ledger = sub.energy()
    assert ledger.total == 0.0 and ledger.initial == 0.0
    rel, vel, stuck = sub.impactor_states()
    assert rel.shape == (0, 2) and vel.shape == (0, 2) and stuck.shape == (0,)


@pytest.mark.parametrize('bad, match', [(dict(dt=0.0), 'dt must be a positive time'),
                                        (dict(stick_rule='glue'), 'stick_rule must be one of'),
                                        (dict(stick_fraction=1.5), 'stick_fraction must be in'),
                                        (dict(forcing=Forcing(2)), 'forcing has 2 inputs')])
@pytest.mark.parametrize('method', ['exact', 'newmark'])
def test_the_shared_arguments_are_checked_once_for_every_integrator(method, bad, match):
    from impact_damper_sim.integrate.simulation import make_integrator
    args = dict(forcing=Forcing(1), dt=1e-3)
    args.update({k: v for k, v in bad.items() if k in args})
    options = {k: v for k, v in bad.items() if k not in args}
    with pytest.raises(ValueError, match=match):
        make_integrator(method, sdof_model(), args['forcing'], args['dt'], **options)


@pytest.fixture(scope='module')
def sdof():
    return load('sdof')


@pytest.mark.parametrize('method, options', CASES,
                         ids=[m + ('/' + '/'.join(o.values()) if o else '') for m, o in CASES])
def test_every_shipped_integrator_keeps_the_contract(sdof, monkeypatch, method, options):
    calls = []
    base_init = IntegratorBase.__init__

    def spy(self, *args, **kwargs):
        calls.append(type(self).__name__)
        base_init(self, *args, **kwargs)

    monkeypatch.setattr(IntegratorBase, '__init__', spy)
    integrator = sdof.make_simulation(method, **options).integrator
    assert isinstance(integrator, IntegratorBase) and not inspect.isabstract(type(integrator))
    assert calls == [type(integrator).__name__]   # super().__init__(...), once
    for name in SHARED:
        assert hasattr(integrator, name), name
    assert integrator.t == 0.0 and integrator.stick_time > 0
    n_imp = len(integrator.model.impactors)
    assert n_imp == 1 and integrator._imp_z.shape == (n_imp, 2)

    q, qd = integrator.state()
    q[:] = np.nan   # a copy: the integrator's state is untouched
    assert np.all(np.isfinite(integrator.state()[0]))
    n = round(0.5 / integrator.dt)   # the first impact comes at 0.21 s
    samples = integrator.advance(n)
    assert samples.t.size == n and samples.displacement.shape[0] == n
    # the output grid is t0 + k dt (a few ulps of summation)
    assert integrator.t == pytest.approx(n * integrator.dt, rel=1e-12)
    events = integrator.take_events()
    assert events.dtype == EVENT_DTYPE and events.size > 0   # the sdof impactor hits
    assert integrator.take_events().size == 0                 # cleared
    assert isinstance(integrator.n_config_changes, int) and integrator.n_config_changes >= 0
    integrator.set_impacts_enabled(False)
    assert not integrator.impacts_enabled and not integrator.impactor_states()[2].any()
