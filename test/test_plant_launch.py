"""``ros2 launch impact_damper_sim plant.launch.py`` (issue 39 item 5) with a two-machine plant
file (sdof and cantilever, a few seconds): both namespaced nodes come up, their /diagnostics
statuses have distinct names and hardware_ids, and the logs are what the plant asked for:
one MCAP holding both machines' topics (``one_log``, the recorder), or one per machine
(``per_machine``, each node's ``record``). Ctrl-C ends every process cleanly.
Processes and isolation as test_ros2_tools.py (its helpers): own DDS domain, own session."""
import time

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
