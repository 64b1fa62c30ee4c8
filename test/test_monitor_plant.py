"""The monitor following a plant of real ``vibration_node``\\ s, launch-free.

Two nodes on scene sdof in ``/pump1`` and ``/pump2`` (one with the plant's hardware_id
SN-1042) share a context with one monitor started with ``namespaces: ['*']``; the nodes do not
step on their own (``start_stepping=False``): the test advances their fake wall clocks and
calls ``tick()``, so each publishes its batches when the test says. The monitor reports when
the test calls ``report()``; its node clock is the real one, which is what its staleness
runs on.
"""
import time

import pytest

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from impact_damper_sim.ros.monitor import VibrationMonitor  # noqa: E402
from node_helpers import FakeClock  # noqa: E402

pytestmark = pytest.mark.ros

WINDOW = 0.2    # the monitor's window (s): stale after 2 windows of its node clock


@pytest.fixture
def plant(ros_context):
    """``(monitor, {namespace: node}, executor, lines)``: two sdof nodes and the monitor."""
    from impact_damper_sim.ros.vibration_node import VibrationNode
    machines = {
        namespace: VibrationNode(
            context=ros_context, namespace=namespace, start_stepping=False,
            clock=FakeClock(), parameter_overrides=[
                Parameter('scene', value='sdof'), Parameter('publish_clock', value=False),
                Parameter('hardware_id', value=hardware_id)])
        for namespace, hardware_id in (('/pump1', 'SN-1042'), ('/pump2', ''))}
    monitor = VibrationMonitor(context=ros_context, parameter_overrides=[
        Parameter('namespaces', value=['*']), Parameter('window', value=WINDOW),
        Parameter('report_period', value=3600.0)])
    executor = SingleThreadedExecutor(context=ros_context)
    for node in [monitor, *machines.values()]:
        executor.add_node(node)
    lines = []
    logger = monitor.get_logger()
    logger.info = lambda text, **_: lines.append(('info', text))
    logger.warning = lambda text, **_: lines.append(('warn', text))
    try:
        yield monitor, machines, executor, lines
    finally:
        executor.shutdown()
        monitor.destroy_node()
        for node in machines.values():
            node.destroy_node()


def spin_until(executor, condition, timeout=20.0):
    """Spin until ``condition()`` holds; fail after ``timeout`` s (wall: a deadline for a
    loaded machine, not a figure)."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, 'condition not met in time'
        executor.spin_once(timeout_sec=0.01)


def matched(monitor, namespaces):
    """Condition: the monitor follows the machines, and each stream it reads is matched."""
    def condition():
        machines = monitor.machines
        if not set(namespaces) <= set(machines):
            return False
        streams = [s for ns in namespaces for s in
                   [*machines[ns].accel_streams.values(), machines[ns].impact_stream]]
        return all(len(machines[ns].accel_streams) for ns in namespaces) and all(
            s.subscription.get_publisher_count() == 1 for s in streams)
    return condition


def run(executor, nodes, seconds):
    """Step ``nodes`` by ``seconds`` of their fake wall clocks, 10 ms a tick, spinning the
    executor between ticks so that the monitor takes each batch."""
    for _ in range(int(round(seconds / 0.01))):
        for node in nodes:
            node._wall.now += 0.01
            node.tick()
        for _ in range(4):
            executor.spin_once(timeout_sec=0.0)


def settle(executor, machine, quiet=0.2):
    """Spin until ``machine`` received no message for ``quiet`` s (wall)."""
    count, since = machine.message_counts['accel'], time.monotonic()
    while time.monotonic() - since < quiet:
        executor.spin_once(timeout_sec=0.01)
        if machine.message_counts['accel'] != count:
            count, since = machine.message_counts['accel'], time.monotonic()


def machine_lines(lines, namespace):
    return [(level, text) for level, text in lines if text.startswith(namespace + ' ')]


def test_two_real_nodes_one_line_each_then_one_stops(plant):
    monitor, machines, executor, lines = plant
    spin_until(executor, matched(monitor, ['/pump1', '/pump2']))
    for node in machines.values():
        node.publish_diagnostics()
    spin_until(executor, lambda: all(monitor.machines[ns].node_hardware_id
                                     for ns in machines))
    # impactor_state goes out on the node's wall-clock timer too; queue one now so that a
    # loaded machine, whose timer has not fired yet, still shows an OK impacts line
    for node in machines.values():
        node.publish_state()
    run(executor, machines.values(), 0.5)
    spin_until(executor, lambda: all(
        m.message_counts['accel'] >= 40 and m.message_counts['impactor_state'] >= 1
        for m in monitor.machines.values()))
    array = monitor.report()

    # one line per machine, namespace first, the same figures as the one-machine lines
    for ns in machines:
        (line,) = machine_lines(lines, ns)
        assert line[0] == 'info', line
        assert line[1].startswith(f'{ns}  accel/'), line
        assert ': rms ' in line[1] and ' samples/s; impacts: ' in line[1], line
    # statuses told apart by name; hardware_id the machine's, as its node reports it
    by_name = {s.name: s for s in array.status}
    assert len(by_name) == len(array.status) == 4
    sensor = next(iter(monitor.machines['/pump1'].accel_streams))
    for ns, hardware_id in (('/pump1', 'SN-1042'), ('/pump2', 'pump2/sdof')):
        for item in (sensor, 'impacts'):
            found = by_name[f'/monitor: {ns}/{item}']
            assert found.level == DiagnosticStatus.OK, (found.name, found.message)
            assert found.hardware_id == hardware_id
    rates = [float({kv.key: kv.value for kv in by_name[f'/monitor: {ns}/{sensor}'].values}
                   ['samples_per_s']) for ns in machines]
    assert all(r > 0 for r in rates), rates

    # pump2 stops; pump1 goes on: after two windows of node clock pump2 is stale (arrivals
    # count when handed to the report thread: the timer does so every report_period, here
    # a report takes what was still in flight when pump2 stopped)
    settle(executor, monitor.machines['/pump2'])
    monitor.report()
    stopped = time.monotonic()
    while time.monotonic() - stopped < 3 * WINDOW:
        run(executor, [machines['/pump1']], 0.02)
        time.sleep(0.01)
    count = len(lines)
    array = monitor.report()
    by_name = {s.name: s for s in array.status}
    gone = by_name[f'/monitor: /pump2/{sensor}']
    assert gone.level == DiagnosticStatus.WARN and gone.message.startswith('stale: no sample')
    assert by_name[f'/monitor: /pump1/{sensor}'].level == DiagnosticStatus.OK
    gone = by_name['/monitor: /pump2/impacts']
    assert gone.level == DiagnosticStatus.WARN and gone.message.startswith('stale: no impacts')
    assert by_name['/monitor: /pump1/impacts'].level == DiagnosticStatus.OK
    new = lines[count:]
    assert [level for level, _ in machine_lines(new, '/pump2')] == ['warn']
    assert 'stale: no sample for' in machine_lines(new, '/pump2')[0][1]
    assert [level for level, _ in machine_lines(new, '/pump1')] == ['info']
