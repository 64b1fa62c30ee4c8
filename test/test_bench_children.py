"""The bench scripts' child programs still run against the node as it is now.

A bench script runs its measurement in a child process whose code is a string of the script
(``bench/node_startup.py``'s ``NODE_CHILD``), reaching into the node's private methods to
drive it by hand. Nothing imports that string, so a change of those methods broke it
silently: ``node._flush(math.inf)`` outlived the signature it called for several stops, and
``bench/node_startup.py`` failed with a TypeError in every node run. Each child is run here
once, warm, on a small scene, and its printed figures are checked for their order and sign.
"""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import pytest

from conftest import next_domain_id

ROOT = Path(__file__).resolve().parents[1]


def _bench(name):
    spec = importlib.util.spec_from_file_location(name, ROOT / 'bench' / f'{name}.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.ros
def test_node_startup_child_times_a_node(monkeypatch):
    pytest.importorskip('rclpy')
    from impact_damper_sim._cache_dir import use_user_cache
    monkeypatch.setenv('ROS_DOMAIN_ID', str(next_domain_id()))
    startup = _bench('node_startup')
    t_import, t_built, t_first, rtf, cpu = startup.run_node('sdof', use_user_cache())
    # wall s from the process start: rclpy imported, then the node built, then its first
    # samples out; then one simulated second stepped (its speed is the bench's figure, not
    # this test's: a loaded machine may run it at any pace)
    assert 0.0 < t_import <= t_built <= t_first
    assert math.isfinite(rtf) and rtf > 0.0
    assert cpu > 0.0


def test_plant_bench_hands_plant_host_the_same_machines(tmp_path, monkeypatch):
    """``bench/plant.py --hosts K`` runs ``plant_host --plant FILE --share I/K``; the plant
    file it writes for ``--scene`` copies loads to the machines the process form starts:
    the same namespaces, scenes and seeds, and the same stagger."""
    monkeypatch.syspath_prepend(str(ROOT / 'bench'))
    plant_bench = _bench('plant')
    from impact_damper_sim.scene.plant import load_plant
    machines = plant_bench.scene_machines('sdof', 3)
    args = plant_bench.host_plant_file(machines, str(tmp_path), stagger=1.5)
    assert args[0] == '--plant'
    plant = load_plant(args[1])
    assert [(m.namespace, m.scene_name, m.seed) for m in plant.machines] == [
        (ns, scene, params['noise_seed']) for ns, scene, params in machines]
    assert plant.stagger == 1.5
    # a plant file given to the bench goes to plant_host as it is, with its override
    assert plant_bench.host_plant_file([], str(tmp_path), 'ten_hpotp') == [
        '--plant', 'ten_hpotp']
    assert plant_bench.host_plant_file([], str(tmp_path), 'ten_hpotp', 2.0) == [
        '--plant', 'ten_hpotp', '--stagger', '2.0']
