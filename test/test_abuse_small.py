"""Issue 29, the smaller items: each reproduced first, then fixed.

* a GetParameters request naming a declared but unset parameter (``overrides``) answers a
  value for every name (PARAMETER_NOT_SET for the unset one), not an empty list;
* ``study report`` on NaN samples says what is NaN, without NumPy RuntimeWarnings;
* the monitor ignores a topic of the wrong type (a String ``accel/fake_sensor``);
* ``study`` and ``study recover`` say what a directory, FIFO or device is.
"""
import os
import subprocess
import sys

import pytest

from node_helpers import call_service

# --- GetParameters with an unset parameter ------------------------------------------------

def _ask(ros_context, node, service, *names_lists):
    """GetParameters answers of ``node``'s ``service`` to each list of names, asked by a
    peer node over DDS."""
    from rcl_interfaces.srv import GetParameters
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    peer = Node('get_parameters_peer', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    executor.add_node(peer)
    try:
        client = peer.create_client(GetParameters, service)
        assert client.wait_for_service(timeout_sec=10.0)
        return [_call(peer, client, GetParameters.Request(names=names), executor)
                for names in names_lists]
    finally:
        executor.shutdown()
        peer.destroy_node()


def _call(node, client, request, executor):
    return call_service(executor, client, request)


@pytest.mark.ros
def test_get_parameters_answers_every_name_including_an_unset_one(ros_context):
    pytest.importorskip('rclpy')
    from rcl_interfaces.msg import ParameterType
    from rclpy.parameter import Parameter

    from impact_damper_sim.ros.vibration_node import VibrationNode

    node = VibrationNode(context=ros_context, start_stepping=False, clock=lambda: 1000.0,
                         parameter_overrides=[Parameter('scene', value='sdof')])
    try:
        names = ['scene', 'overrides', 'real_time_factor']
        both, alone, stranger = _ask(ros_context, node, '/vibration_node/get_parameters',
                                     names, ['overrides'], ['scene', 'no_such'])
        assert len(both.values) == len(names)
        scene, overrides, rtf = both.values
        assert scene.type == ParameterType.PARAMETER_STRING and scene.string_value == 'sdof'
        assert overrides.type == ParameterType.PARAMETER_NOT_SET   # ROS 2: unset
        assert rtf.type == ParameterType.PARAMETER_DOUBLE
        # alone, too, and an undeclared name keeps rclpy's answer (no values)
        assert [v.type for v in alone.values] == [ParameterType.PARAMETER_NOT_SET]
        assert len(stranger.values) == 0
    finally:
        node.destroy_node()


@pytest.mark.ros
def test_the_monitor_answers_an_unset_sensors_parameter(ros_context):
    pytest.importorskip('rclpy')
    from rcl_interfaces.msg import ParameterType

    from impact_damper_sim.ros.monitor import VibrationMonitor

    monitor = VibrationMonitor(context=ros_context, namespace='/unset_probe')
    try:
        answer, = _ask(ros_context, monitor, '/unset_probe/monitor/get_parameters',
                       ['sensors', 'window'])
        assert [v.type for v in answer.values] == [ParameterType.PARAMETER_NOT_SET,
                                                   ParameterType.PARAMETER_DOUBLE]
    finally:
        monitor.destroy_node()


# --- a directory, a FIFO or a device given as a scene or a log --------------------------------

@pytest.fixture
def not_files(tmp_path):
    """Paths that exist but are not regular files: ``(path, what the message says)``."""
    out = []
    for suffix in ('yaml', 'mcap'):
        d = tmp_path / f'dir.{suffix}'
        d.mkdir()
        fifo = tmp_path / f'fifo.{suffix}'
        os.mkfifo(fifo)
        zero = tmp_path / f'zero.{suffix}'
        zero.symlink_to('/dev/zero')
        out.append([(d, 'a directory'), (fifo, 'a FIFO'), (zero, 'a character device')])
    return out


def _study(*args):
    return subprocess.run([sys.executable, '-m', 'impact_damper_sim.cli.study', *args],
                          capture_output=True, text=True, timeout=60)


def test_study_says_what_a_path_is_that_is_not_a_file(not_files, tmp_path):
    """'does not exist' for a directory, FIFO or /dev/zero; recover blocked on a FIFO."""
    scenes, logs = not_files
    runs = [(['simulate', str(p)], what) for p, what in scenes]
    runs += [(['report', str(p)], what) for p, what in logs]
    runs += [(['recover', str(p), str(tmp_path / 'out.mcap')], what) for p, what in logs]
    for args, what in runs:
        proc = _study(*args)   # a FIFO opened for reading would block: timeout = failure
        assert proc.returncode == 2, (args, proc.stderr)
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and what in lines[0] and 'not a regular file' in lines[0], \
            (args, proc.stderr)
        assert 'does not exist' not in lines[0] and 'empty' not in lines[0]
    assert not (tmp_path / 'out.mcap').exists()


def test_the_scene_loader_never_opens_a_fifo(tmp_path):
    """load_yaml (the node's loader too) checks the kind before opening the path."""
    import threading

    from impact_damper_sim.scene.loading import load_yaml
    from impact_damper_sim.scene.schema import SceneError
    fifo = tmp_path / 'g.yaml'
    os.mkfifo(fifo)
    result = {}

    def read():
        try:
            load_yaml(str(fifo))
        except SceneError as exc:
            result['error'] = str(exc)

    t = threading.Thread(target=read, daemon=True)
    t.start()
    t.join(5.0)
    assert not t.is_alive(), 'load_yaml blocked on a FIFO'
    assert 'a FIFO, not a regular file' in result['error']
