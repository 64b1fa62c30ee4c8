"""What a ``vibration_node`` holds in memory (issue 39 item 2; figures in
docs/bench/node-memory.md, by bench/node_memory.py).

A node's 220 MB are the libraries it needs (NumPy, SciPy, Numba with LLVM, rclpy) and the
compiled kernels; its own model and buffers are about 1 MB. These tests keep it so without
timing or RSS figures (both depend on the machine): the node never imports what only offline
work, plots or studies need, and one more machine in a process keeps little of its own."""
import json
import subprocess
import sys

import pytest

#: modules a node must never import: plotting, studies and the offline-only SciPy parts
#: (each would add MBs to every node of a plant, bench/node_memory.py's breakdown)
NEVER = ('matplotlib', 'scipy.signal', 'scipy.optimize', 'scipy.stats', 'scipy.interpolate',
         'impact_damper_sim.studies', 'impact_damper_sim.cli', 'dask')


def _modules_after(code, then=''):
    """``NEVER`` modules in ``sys.modules`` after ``code`` runs in a fresh interpreter (and
    before ``then``, its clean-up)."""
    probe = (f'{code}\nimport json, sys\n'
             f'print(json.dumps([m for m in {NEVER!r} if m in sys.modules]))\n{then}')
    done = subprocess.run([sys.executable, '-c', probe], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_the_probe_sees_an_offline_import():
    """The check can fail: an import of one of them is seen."""
    assert _modules_after('import scipy.optimize') == ['scipy.optimize']


def test_importing_the_node_imports_nothing_offline():
    pytest.importorskip('rclpy')
    assert _modules_after('import impact_damper_sim.ros.vibration_node') == []


@pytest.mark.ros
def test_a_running_machine_imports_nothing_offline():
    """Building a node (scene, FE model, modal reduction, kernels) and stepping it 1 s: the
    imports made on the way (inside functions) stay clear of them too. (Its shutdown may
    import studies.log_errors, a few kB, to word a recording's end: not checked.)"""
    pytest.importorskip('rclpy')
    from conftest import next_domain_id
    code = (
        'import rclpy\n'
        'from rclpy.parameter import Parameter\n'
        'from impact_damper_sim.ros.vibration_node import VibrationNode\n'
        f'rclpy.init(domain_id={next_domain_id()})\n'
        'clock = [0.0]\n'
        "node = VibrationNode(start_stepping=False, clock=lambda: clock[0], "
        "parameter_overrides=[Parameter('scene', value='rbs')])\n"
        'for _ in range(10):\n'
        '    clock[0] += 0.1\n'
        '    node.tick()\n'
        'assert node.live.t >= 0.99, node.live.t\n')
    assert _modules_after(code, then='node.destroy_node()\nrclpy.try_shutdown()\n') == []


@pytest.mark.ros
def test_one_more_machine_keeps_little_of_its_own(ros_context):
    """A second hpotp machine in a process, stepped 1 s, keeps under 8 MB of Python and
    NumPy memory (tracemalloc; DDS's native memory is not traced): its model (16 modes,
    its impactors) and per-chunk buffers are small; a buffer sized by anything but need
    (a whole run's samples, a recording ring per topic) would not be. About 1 MB today."""
    import tracemalloc

    from node_helpers import FakeClock, make_node
    first = make_node(ros_context, scene='hpotp', name='first')   # kernels loaded once
    clock = FakeClock()
    tracemalloc.start()
    try:
        second = make_node(ros_context, scene='hpotp', name='second', clock=clock)
        for _ in range(10):   # 1 s in steps under the pacer's max_lag (0.25 s)
            clock.now += 0.1
            second.tick()
        held, _ = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    try:
        assert second.live.t >= 0.99   # it did step the second
        assert held < 8e6, f'one more machine holds {held / 1e6:.1f} MB of its own'
    finally:
        second.destroy_node()
        first.destroy_node()
