"""``ros2 launch impact_damper_sim plant.launch.py`` (issue 39 item 5) with a two-machine plant
file (sdof and cantilever, a few seconds): both namespaced nodes come up, their /diagnostics
statuses have distinct names and hardware_ids, and the logs are what the plant asked for:
one MCAP holding both machines' topics (``one_log``, the recorder), or one per machine
(``per_machine``, each node's ``record``). Ctrl-C ends every process cleanly. Which processes
``hosts:=K`` starts is read off the launch description without running it.
Processes and isolation as test_ros2_tools.py (its helpers): own DDS domain, own session."""
import importlib.util
import time
from pathlib import Path

import pytest

from test_ros2_tools import (
    PKG,
    ROS2,
    START_TIMEOUT,
    Proc,
    check_launch_stopped,
    mcap_summary,
    needs_launch,
    ros_env,
    stop_daemon,
)

PLANT = """
plant: pair
seed: 11
machines:
  - {namespace: m1, scene: sdof, hardware_id: SN-0001}
  - {namespace: m2, scene: cantilever}
"""


def _statuses(env, seconds):
    """{status name: hardware_id} of what /diagnostics carried for ``seconds`` (s)."""
    rclpy = pytest.importorskip('rclpy')
    from diagnostic_msgs.msg import DiagnosticArray
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=int(env['ROS_DOMAIN_ID']))
    seen = {}
    try:
        node = rclpy.create_node('diag_tap', context=ctx)
        node.create_subscription(DiagnosticArray, '/diagnostics', lambda m: seen.update(
            {s.name: s.hardware_id for s in m.status}), 10)
        from rclpy.executors import SingleThreadedExecutor
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        end = time.monotonic() + seconds
        while time.monotonic() < end and not {'/m1/vibration_node: simulation',
                                              '/m2/vibration_node: simulation'} <= set(seen):
            ex.spin_once(timeout_sec=0.1)
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
    return seen


@needs_launch
@pytest.mark.parametrize('mode', ['one_log', 'per_machine'])
def test_a_two_machine_plant_launches_tells_its_machines_apart_and_records(tmp_path, mode):
    plant = tmp_path / 'pair.yaml'
    plant.write_text(PLANT)
    logs = tmp_path / 'logs'
    env = ros_env(tmp_path)
    proc = Proc(f'{ROS2} launch {PKG} plant.launch.py plant:={plant} record:={logs} '
                f'record_mode:={mode} monitor:=false', env, tmp_path, tty=True)
    problems = []
    try:
        for ns in ('m1', 'm2'):
            assert proc.wait_for(rf'\[{ns}\.vibration_node\]: .*accelerometers at',
                                 START_TIMEOUT), proc.output
        seen = _statuses(env, 30.0)
        # the names carry each node's full name; the hardware_ids the plant's or ns/scene
        assert seen.get('/m1/vibration_node: simulation') == 'SN-0001', seen
        assert seen.get('/m2/vibration_node: simulation') == 'm2/cantilever', seen
        time.sleep(2.0)   # seconds of samples in the logs
        rc = proc.interrupt()
        check_launch_stopped(proc, rc, problems)
    finally:
        proc.close()
        stop_daemon(env, tmp_path)
    assert not problems, '\n\n'.join(problems)
    files = sorted(p.name for p in logs.glob('*.mcap'))
    if mode == 'one_log':
        assert files == ['pair.mcap'], files
        count, topics = mcap_summary(logs / 'pair.mcap')
        for ns, sensor in (('m1', 'sdof_primary'), ('m2', 'cantilever_tip')):
            assert {f'/{ns}/accel/{sensor}/batch', f'/{ns}/accel/{sensor}',
                    f'/{ns}/impacts'} <= topics, sorted(topics)
        assert '/diagnostics' in topics and count > 1000, (count, sorted(topics))
        assert 'recorded' in proc.output and 'pair.mcap' in proc.output
    else:
        assert files == ['m1.mcap', 'm2.mcap'], files
        for ns, other in (('m1', 'm2'), ('m2', 'm1')):
            count, topics = mcap_summary(logs / f'{ns}.mcap')
            assert any(t.startswith(f'/{ns}/accel/') for t in topics), sorted(topics)
            assert not any(t.startswith(f'/{other}/') for t in topics), sorted(topics)
            assert count > 1000, count


@needs_launch
def test_a_bad_plant_starts_nothing_and_names_every_problem(tmp_path):
    """The plant file and each machine's faults (against its scene's accelerometers) are
    checked before any process starts."""
    from test_ros2_tools import run
    plant = tmp_path / 'bad.yaml'
    plant.write_text("""
machines:
  - {namespace: m1, scene: sdof,
     faults: [{kind: gain, accelerometer: sdof_primari, gain: 3},
              {kind: spikes, accelerometer: sdof_primary, rate: -1 Hz, amplitude: 1 g}]}
""")
    env = ros_env(tmp_path)
    rc, out = run(f'{ROS2} launch {PKG} plant.launch.py plant:={plant}', env, tmp_path)
    assert rc not in (0, None), out
    assert 'process started' not in out, out
    assert ("machines[0].faults[0].accelerometer: 'sdof_primari' is not an accelerometer of "
            "this scene; did you mean 'sdof_primary'?") in out, out
    assert 'machines[0].faults[1].rate' in out, out
    plant.write_text('machines:\n  - {namespace: m1, scene: nosuch}\n')
    rc, out = run(f'{ROS2} launch {PKG} plant.launch.py plant:={plant}', env, tmp_path)
    assert rc not in (0, None) and "machines[0].scene: unknown scene 'nosuch'" in out, out


# --------------------------------------------------------- the processes, not started
LAUNCH_FILE = Path(__file__).resolve().parent.parent / 'launch' / 'plant.launch.py'


def _planned_processes(**arguments):
    """``[(executable, namespace, arguments)]`` the launch file would start for these launch
    arguments (the defaults for the others), read off its actions without running any."""
    pytest.importorskip('launch', reason='the ROS 2 launch package is not installed')
    pytest.importorskip('launch_ros', reason='the ROS 2 launch_ros package is not installed')
    from launch.launch_context import LaunchContext
    from launch.substitutions import LocalSubstitution
    from launch.utilities import perform_substitutions
    from launch_ros.actions import Node
    spec = importlib.util.spec_from_file_location('plant_launch', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    context = LaunchContext()
    for action in module.generate_launch_description().entities:
        default = getattr(action, 'default_value', None)
        if default is not None:
            context.launch_configurations[action.name] = perform_substitutions(context,
                                                                               default)
    context.launch_configurations.update(arguments)
    planned = []
    for action in module._plant_actions(context):
        assert isinstance(action, Node), action
        # the last item is the ROS arguments, substituted only when the process starts
        args = [perform_substitutions(context, item) for item in action.cmd[1:]
                if not any(isinstance(s, LocalSubstitution) for s in item)]
        planned.append((action.node_executable, action._Node__node_namespace, args))
    return planned


def test_hosts_5_starts_five_plant_hosts_each_a_share_and_no_vibration_node():
    from impact_damper_sim.scene.plant import load_plant
    source = load_plant('ten_hpotp').source
    planned = _planned_processes(plant='ten_hpotp', hosts='5', monitor='false')
    assert [exe for exe, _, _ in planned] == ['plant_host'] * 5, planned
    for i, (_, namespace, args) in enumerate(planned):
        assert namespace is None, planned   # a namespace remap would move every machine
        assert args[:2] == ['--plant', source], args
        assert args[args.index('--share') + 1] == f'{i}/5', args
        assert args[args.index('--record-mode') + 1] == 'none', args


def test_hosts_with_per_machine_logs_give_every_host_the_same_directory(tmp_path):
    planned = _planned_processes(plant='ten_hpotp', hosts='2', monitor='false',
                                 record=str(tmp_path / 'logs'))
    assert [exe for exe, _, _ in planned] == ['plant_host'] * 2, planned
    for _, _, args in planned:
        assert args[args.index('--record-mode') + 1] == 'per_machine', args
        assert args[args.index('--record-dir') + 1] == str(tmp_path / 'logs'), args
    one_log = _planned_processes(plant='ten_hpotp', hosts='2', monitor='false',
                                 record=str(tmp_path / 'one'), record_mode='one_log')
    assert [exe for exe, _, _ in one_log] == ['recorder', 'plant_host', 'plant_host']
    assert all('--record-dir' not in args for _, _, args in one_log[1:]), one_log
    # the recorder writes the one log: the hosts record nothing and say nothing of it
    assert all(args[args.index('--record-mode') + 1] == 'none'
               for _, _, args in one_log[1:]), one_log


def test_by_default_each_machine_is_a_vibration_node_process_of_its_own():
    from impact_damper_sim.scene.plant import load_plant
    planned = _planned_processes(plant='ten_hpotp', monitor='false')
    assert [exe for exe, _, _ in planned] == ['vibration_node'] * 10, planned
    assert [ns for _, ns, _ in planned] == load_plant('ten_hpotp').namespaces


@pytest.mark.parametrize('hosts', ['11', '-1', 'two'])
def test_hosts_beyond_the_machines_or_not_a_count_is_refused_naming_it(hosts):
    with pytest.raises(RuntimeError, match=rf'^hosts:={hosts}: give 0 .* or 1 to 10 '):
        _planned_processes(plant='ten_hpotp', hosts=hosts, monitor='false')


def test_a_stagger_reaches_every_plant_host_and_starts_no_process_late():
    """The stagger spreads the rotors' run-ups (the machines' schedules), not the processes:
    every node starts with the launch; a plant_host gets the launch's stagger."""
    hosts = _planned_processes(plant='ten_hpotp', monitor='false', stagger='2', hosts='3')
    assert [exe for exe, _, _ in hosts] == ['plant_host'] * 3, hosts
    assert all(args[args.index('--stagger') + 1] == '2.0' for _, _, args in hosts), hosts
    nodes = _planned_processes(plant='ten_hpotp', monitor='false', stagger='2')
    assert [exe for exe, _, _ in nodes] == ['vibration_node'] * 10, nodes


@pytest.mark.parametrize('stagger', ['-1', '61', 'soon'])
def test_a_stagger_out_of_range_is_refused_naming_it(stagger):
    with pytest.raises(RuntimeError, match=rf'^stagger:={stagger}: give seconds from 0 to 60'):
        _planned_processes(plant='ten_hpotp', stagger=stagger, monitor='false')
