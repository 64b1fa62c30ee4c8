"""The model-size budget (issue 29): estimated from the scene before anything is built.

10,000 impactors ran 64 s and reached 4.5 GB with exit 0: the 4 GiB refusal counted only
the sample arrays. Now :func:`impact_damper_sim.scene.model_budget.model_estimate` counts DOFs,
modes, impactors and stuck configurations up front, ``build`` refuses an over-budget scene
in one line before building it (``study``: exit 2; the node: one line, exit 2), and the
stuck configurations a run keeps are bounded.
"""
import re
import time
from pathlib import Path

import numpy as np
import pytest

from impact_damper_sim.cli.study import main as study
from impact_damper_sim.integrate import memory
from impact_damper_sim.integrate.memory import memory_limit
from impact_damper_sim.scene import build as build_mod
from impact_damper_sim.scene.build import load
from impact_damper_sim.scene.catalog import available_scenes, validated
from impact_damper_sim.scene.model_budget import (
    MAX_IMPACTORS,
    ModelTooLarge,
    check_model,
    model_estimate,
)
from impact_damper_sim.scene.schema import SceneError
from node_refusal import node_refusal

SDOF = Path(__file__).resolve().parents[1] / 'config' / 'scenes' / 'sdof.yaml'


def many_impactors(path, n, masses=None):
    """The sdof scene with ``n`` impactors (interchangeable unless ``masses`` differ)."""
    head = SDOF.read_text().split('\nimpactors:')[0]
    items = ''.join(
        f'  - {{name: d{i}, kind: sdof, node: 0, dof: uy, '
        f'mass_ratio: {(masses[i] if masses else 0.1 / n):.6g}, cor: 0.5, clearance: 4.8 mm}}\n'
        for i in range(n))
    path.write_text(head + '\nimpactors:\n' + items + '\nsimulation:\n  method: exact\n'
                    '  dt: 0.1 ms\n  duration: 0.2 s\n  window: 0.1 s\n')
    return path


def _no_build(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError('the model was built before the budget was checked')
    monkeypatch.setattr(build_mod, '_build_fe', refuse)


def test_every_shipped_scene_is_well_under_the_budget():
    for name in available_scenes():
        scene, _ = validated(name)
        estimate = check_model(scene)
        assert estimate.total < memory_limit() / 100, (name, estimate)


def test_more_impactors_than_the_limit_are_refused_before_building(tmp_path, monkeypatch,
                                                                   capsys):
    scene, _ = validated(many_impactors(tmp_path / 'ok.yaml', MAX_IMPACTORS))
    check_model(scene)   # the limit: ok
    over = dict(scene, impactors=scene['impactors'] + scene['impactors'][:1])
    with pytest.raises(ModelTooLarge, match=r"scene key 'impactors': 1,001 impactors, over "
                                            r'the limit of 1,000'):
        check_model(over)   # a list that grew past it (overrides): refused before building
    # a scene file is refused sooner, by the loader's pre-scan at the 1,001st impactor (the
    # rest of the file unread: test_abuse_inputs.py)
    path = many_impactors(tmp_path / 'many.yaml', MAX_IMPACTORS + 1)
    _no_build(monkeypatch)
    with pytest.raises(SceneError, match=r"scene key 'impactors': over the limit of 1,000 "
                                         r'impactors \(allowed 0 to 1,000; impactor 1,001 '):
        load(path)
    assert study(['simulate', str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('study: error: ') and \
        'over the limit of 1,000 impactors' in err[0], err


def test_dofs_over_the_budget_are_refused_with_the_estimate_and_the_limit(monkeypatch, capsys):
    """100,000 elements (600,006 DOFs): dense condensation of 2.9 TB, refused up front."""
    _no_build(monkeypatch)
    start = time.process_time()   # CPU, not wall: another job on the machine does not count
    rc = study(['simulate', 'cantilever', '--set', 'structure.lines.0.n_elements=100000'])
    assert rc == 2 and time.process_time() - start < 30
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert re.search(r'model too large: 600,006 DOFs \(100,001 nodes\), .* would need about '
                     r'[0-9.e+]+ GiB of memory \(limit [0-9.]+ GiB\): use fewer nodes '
                     r'\(structure\.lines\[\]\.n_elements', line), line


def test_the_estimate_counts_configurations_and_modes():
    scene, _ = validated('hpotp')
    e = model_estimate(scene)
    assert (e.n_impactors, e.n_modes, e.n_dof) == (12, 10, 6 * 18)
    assert e.n_configurations == 13   # 12 interchangeable impactors: 0 to 12 stuck
    assert set(e.terms) == {'dofs', 'modes', 'impactors', 'configurations'}
    assert e.total == sum(e.terms.values())
    with pytest.raises(ModelTooLarge, match=r'model too large: .*12 impactors.* would need '
                                            r'about .* GiB of memory \(limit [0-9.e-]+ GiB\)'):
        check_model(scene, limit=1000)


def test_samples_share_the_limit_with_the_model(tmp_path, capsys, monkeypatch):
    path = many_impactors(tmp_path / 'some.yaml', 400)
    scene, _ = validated(path)
    model = model_estimate(scene).total
    samples = memory.sample_bytes(2000, 1)   # 0.2 s at 0.1 ms
    monkeypatch.setattr(memory, 'memory_limit', lambda: model + samples - 1)
    assert study(['simulate', str(path)]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "samples would need about" in line and "with the model's" in line, line


def test_the_configurations_a_run_keeps_are_bounded(monkeypatch):
    """Switching through Python, at most ``cache_limit`` configurations are kept, the least
    recently used dropped and rebuilt: the same events as without a bound."""
    import tempfile

    import impact_damper_sim.integrate.exact as exact_mod
    with tempfile.TemporaryDirectory() as tmp:
        # six impactors of different masses: 64 stuck sets, each its own configuration (42
        # of them reached in 1 s)
        scene = load(many_impactors(Path(tmp) / 'six.yaml', 6,
                                    masses=[0.01, 0.012, 0.014, 0.016, 0.018, 0.02]),
                     overrides=['simulation.duration=1 s', 'simulation.window=0.5 s']
                     + [f'impactors.{i}.cor=0' for i in range(6)])   # plastic: they stick
    monkeypatch.setattr(exact_mod, 'MAX_TABLE_SLOTS', 0)   # switch through Python

    def run(keep):
        monkeypatch.setattr(memory, 'MAX_CACHED_CONFIGURATIONS', keep)
        monkeypatch.setattr(memory, 'MAX_CACHE_BYTES', 1)
        sim = scene.make_simulation()
        samples = sim.advance_to(1.0)
        return sim, samples, sim.take_events()

    free_sim, free_samples, free_events = run(10 ** 6)
    visited = len(free_sim.integrator._flows)
    assert visited > 4, 'the run must visit more configurations than are kept'
    sim, samples, events = run(4)
    assert len(sim.integrator._flows) <= 4 and len(sim.integrator._tables) <= 4
    assert np.array_equal(events, free_events)
    assert np.array_equal(samples.displacement, free_samples.displacement)


@pytest.mark.ros
def test_the_node_refuses_an_over_budget_scene_in_one_line(tmp_path):
    pytest.importorskip('rclpy')
    path = many_impactors(tmp_path / 'many.yaml', MAX_IMPACTORS + 1)
    lines, stderr = node_refusal(path, timeout=120)
    assert len(lines) == 1 and 'over the limit of 1,000 impactors' in lines[0], stderr
    assert 'Traceback' not in stderr
