"""Switching the impact dampers off and on during a run (``Simulation.set_impacts_enabled``).

Off must remove every impact from then on and leave the structure a linear oscillator; on
must bring impacts back; the structural state is continuous across both switches and the
energy ledger still balances.
"""
import numpy as np
import pytest

from impact_damper_sim.scene.build import load

LEDGER_RTOL = 1e-9   # ledger residual relative to the forcing work over the run


def _sim(method, **overrides):
    scene = load('sdof', overrides=[f'{k}={v}' for k, v in overrides.items()])
    return scene, scene.make_simulation(method=method, dt=1e-3)


@pytest.mark.parametrize('method', ['exact', 'newmark'])
def test_off_removes_impacts_then_on_restores_them(method):
    scene, sim = _sim(method)
    sim.advance_to(2.0)
    assert np.sum(sim.take_events()['kind'] == 0) > 50   # the damper works: ~2 impacts/cycle
    sim.set_impacts_enabled(False)
    assert not sim.impacts_enabled
    assert not any(s['stuck'] for s in sim.impactor_states())
    sim.advance_to(6.0)
    assert sim.take_events().size == 0
    sim.set_impacts_enabled(True)
    rel = sim.impactor_states()[0]['position']
    assert abs(rel[0]) < 1e-15   # back at the housing centre
    sim.advance_to(7.0)
    assert np.sum(sim.take_events()['kind'] == 0) > 5
    led = sim.energy()
    assert abs(led.residual) <= LEDGER_RTOL * max(abs(led.forcing), led.initial, 1e-12) + 1e-12


def test_off_is_the_linear_oscillator_and_the_state_is_continuous():
    """After the switch the response equals a linear run started from the same state."""
    scene, sim = _sim('exact')
    sim.advance_to(1.5)
    q, qd = sim.integrator.state()
    sim.set_impacts_enabled(False)
    q1, qd1 = sim.integrator.state()
    np.testing.assert_array_equal(q, q1)
    np.testing.assert_array_equal(qd, qd1)
    off = sim.advance_to(2.5).displacement[:, 0]
    # reference: the same structure with a wall so far away that it is never reached
    from impact_damper_sim.integrate.exact import ExactPropagator
    from impact_damper_sim.integrate.simulation import Simulation
    ref = Simulation(scene.model, scene.forcing, dt=1e-3, q0=q, qd0=qd, t0=1.5,
                     stick_fraction=scene.scene['simulation']['stick_fraction'])
    ref.set_impacts_enabled(False)
    assert isinstance(ref.integrator, ExactPropagator)
    lin = ref.advance_to(2.5).displacement[:, 0]
    np.testing.assert_allclose(off, lin, rtol=0, atol=1e-12 * np.abs(lin).max())
