"""Across hosts (issue 39 item 6): a node on one host, the monitor and a recorder on another.

Two network namespaces joined by a veth pair stand in for two hosts (``tools/netns_hosts.py``:
own interfaces, addresses, UDP ports and ``/dev/shm`` each). On host A runs
``vibration_node`` (scene sdof, real time); on host B the package's recorder
(``impact_damper_recorder``, raw subscriptions into an MCAP file), the monitor
(``impact_damper_monitor``) and a raw rclpy subscriber of this file (``probe``: run as
``python test/test_across_hosts.py probe``), which counts what arrives so the test knows when
enough sim time has gone by without a wall-clock wait. Everything runs from ``.venv/bin``
with only the environment set per host (no ``ros2 run``, no launch).

* ``test_subnet_reaches_the_other_host``: both hosts ``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET``
  (the ROS default; multicast discovery over the link). The recorder on B holds every batch
  from its first to its last (the node's rate: one batch per ``tick_period`` of sim time,
  ``sample_rate x tick_period`` rows each; at most 1 % missing, BATCH_QOS is reliable), the
  node's ``/diagnostics`` status under its fully qualified name, and host B's end of the link
  received at least the bytes of those batches (they crossed the veth, not shared memory);
  B's graph lists ``/vibration_node``; the monitor on B logs the accelerometer of A.
* ``test_localhost_stays_on_its_host``: both ``LOCALHOST``: a probe on A receives the node's
  batches, a probe on B at the same time receives nothing and does not see the node.
* ``test_static_peers_cross_a_router``: the hosts on two subnets with a router between them
  (multicast is not routed). The node keeps the defaults; a probe on B with
  ``ROS_STATIC_PEERS=<A>`` receives the batches, a probe on B without receives nothing.
* ``test_a_static_peer_reaches_four_processes_of_a_host`` (slow: seven processes, 13 s here):
  across the router, a node started as host A's fifth ROS process is not reached from B
  naming A, and is once it names B.

Skipped, saying why, without root, ``ip``/``unshare``, network namespaces or rclpy
(``test_the_skip_says_why`` checks the reasons anywhere).
"""
import importlib.util
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent            # the venv's console scripts
_spec = importlib.util.spec_from_file_location('netns_hosts', ROOT / 'tools' / 'netns_hosts.py')
netns_hosts = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(netns_hosts)

#: the node's accelerometer batches (scene sdof: one accelerometer, 2000 Hz)
BATCH_TOPIC = '/accel/sdof_primary/batch'
SAMPLE_RATE = 2000.0      # Hz, sdof's full rate
TICK_PERIOD = 0.01        # s, sim time a batch covers (the node's default)
#: batches (sim time / TICK_PERIOD) a receiver counts before the run stops: 3 s of sim time
ENOUGH = 300
#: the longest wait for ENOUGH batches (s): a deadline for a loaded machine, not a figure
DEADLINE = 90.0
DOMAIN_ID = 87            # this file's domain (namespaces isolate it anyway)
STATUS_NAME = '/vibration_node: simulation'


# --- the probe: a raw subscriber, run on a host as a script ----------------------------------

def probe_main(out):
    """Count batches and /diagnostics statuses until SIGINT/SIGTERM; write ``out`` (JSON)
    every 0.2 s: ``batches``, ``statuses`` (names seen), ``nodes`` (the graph, fully
    qualified)."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.signals import SignalHandlerOptions
    from sensor_msgs.msg import PointCloud2

    from impact_damper_sim.ros.interface import BATCH_QOS, DIAGNOSTICS_QOS

    stop = []
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGINT, lambda *_: stop.append(True))
    signal.signal(signal.SIGTERM, lambda *_: stop.append(True))
    node = rclpy.create_node('probe')
    state = {'batches': 0, 'statuses': [], 'nodes': []}

    def on_batch(_msg):
        state['batches'] += 1

    def on_diagnostics(msg):
        state['statuses'] = sorted(set(state['statuses']) | {s.name for s in msg.status})

    node.create_subscription(PointCloud2, BATCH_TOPIC, on_batch, BATCH_QOS)
    node.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, DIAGNOSTICS_QOS)

    def write():
        graph = {f"{ns.rstrip('/')}/{name}" for name, ns in node.get_node_names_and_namespaces()}
        state['nodes'] = sorted(set(state['nodes']) | graph)
        tmp = out + '.tmp'
        with open(tmp, 'w') as f:
            json.dump(state, f)
        os.replace(tmp, out)

    due = 0.0
    while not stop:
        rclpy.spin_once(node, timeout_sec=0.05)
        if time.monotonic() >= due:
            write()
            due = time.monotonic() + 0.2
    write()
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


# --- helpers ---------------------------------------------------------------------------------

@pytest.fixture(scope='module')
def can_make_hosts():
    """Skip, saying why, where two namespaces cannot be made or rclpy is missing."""
    pytest.importorskip('rclpy', reason='needs rclpy (the ROS 2 Jazzy wheels)')
    reason = netns_hosts.unavailable_reason()
    if reason:
        pytest.skip(f'two hosts on one machine: {reason}')


def host_env(tmp_path, **ros):
    """The environment of a process on a host: this one's, without the discovery settings
    of the test session (conftest keeps it on LOCALHOST), plus ``ros`` (``range`` ->
    ROS_AUTOMATIC_DISCOVERY_RANGE, ``peers`` -> ROS_STATIC_PEERS)."""
    env = {k: v for k, v in os.environ.items()
           if k not in ('ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_STATIC_PEERS',
                        'ROS_LOCALHOST_ONLY')}
    env.update(AMENT_PREFIX_PATH=sys.prefix, ROS_DOMAIN_ID=str(DOMAIN_ID),
               ROS_LOG_DIR=str(tmp_path / 'ros_log'), PYTHONUNBUFFERED='1')
    if ros.get('range'):
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = ros['range']
    if ros.get('peers'):
        env['ROS_STATIC_PEERS'] = ros['peers']
    return env


class Runs:
    """The processes a test started on its hosts, each with its log file; all ended at exit."""

    def __init__(self, hosts, tmp_path):
        self.hosts, self.tmp = hosts, tmp_path
        self.procs = {}
        self.stopped = set()

    def start(self, label, host, argv, **ros):
        log = open(self.tmp / f'{label}.log', 'w')
        proc = self.hosts.popen(host, [str(a) for a in argv], env=host_env(self.tmp, **ros),
                                stdout=log, stderr=subprocess.STDOUT, cwd=self.tmp)
        log.close()
        self.procs[label] = proc
        return proc

    def probe(self, label, host, **ros):
        self.start(label, host, [sys.executable, Path(__file__).resolve(), 'probe',
                                 self.tmp / f'{label}.json'], **ros)

    def state(self, label):
        path = self.tmp / f'{label}.json'
        return json.loads(path.read_text()) if path.exists() else {
            'batches': 0, 'statuses': [], 'nodes': []}

    def log(self, label):
        return (self.tmp / f'{label}.log').read_text()

    def wait_for_batches(self, label, more=ENOUGH):
        """Wait until ``label`` counted ``more`` batches more than now (fail after DEADLINE s,
        with the logs)."""
        goal = self.state(label)['batches'] + more
        self._wait(lambda: self.state(label)['batches'] >= goal,
                   lambda: f'{label} counted {self.state(label)["batches"]} batches of {goal}')

    def wait_for_log(self, label, text):
        """Wait until ``label``'s log holds ``text`` (fail after DEADLINE s, with the logs)."""
        self._wait(lambda: text in self.log(label), lambda: f'{label} never logged {text!r}')

    def _wait(self, done, what):
        end = time.monotonic() + DEADLINE
        while not done():
            dead = [k for k, p in self.procs.items()
                    if p.poll() is not None and k not in self.stopped]
            if dead or time.monotonic() > end:
                logs = '\n'.join(f'--- {k}\n{self.log(k)[-1500:]}' for k in self.procs)
                pytest.fail(f'{what()} (ended early: {dead}); logs:\n{logs}')
            time.sleep(0.1)

    def stop(self, *labels, timeout=30.0):
        """SIGINT (the process is the command itself: the host wrapper execs it), wait;
        return the exit codes."""
        for label in labels:
            self.stopped.add(label)
            self.procs[label].send_signal(signal.SIGINT)
        codes = []
        for label in labels:
            try:
                codes.append(self.procs[label].wait(timeout))
            except subprocess.TimeoutExpired:
                self.procs[label].kill()
                codes.append(self.procs[label].wait())
        return codes

    def close(self):
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()


def _runs(tmp_path, routed):
    with netns_hosts.TwoHosts(routed=routed) as hosts:
        r = Runs(hosts, tmp_path)
        try:
            yield r
        finally:
            r.close()


@pytest.fixture
def runs(can_make_hosts, tmp_path):
    """Two hosts on one link and a :class:`Runs` on them."""
    yield from _runs(tmp_path, routed=False)


@pytest.fixture
def routed_runs(can_make_hosts, tmp_path):
    """Two hosts on two subnets joined by a router and a :class:`Runs` on them."""
    yield from _runs(tmp_path, routed=True)


NODE = [BIN / 'vibration_node', '--ros-args', '-p', 'scene:=sdof']


def read_mcap(path):
    """Batches (header stamps s, rows, CDR bytes) and the /diagnostics statuses (name,
    hardware_id) of an MCAP file."""
    from diagnostic_msgs.msg import DiagnosticArray
    from mcap.reader import make_reader
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import PointCloud2

    stamps, rows, size, statuses = [], [], 0, set()
    with open(path, 'rb') as f:
        for _, channel, message in make_reader(f).iter_messages():
            if channel.topic == BATCH_TOPIC:
                msg = deserialize_message(message.data, PointCloud2)
                stamps.append(msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec)
                rows.append(msg.width * msg.height)
                size += len(message.data)
            elif channel.topic == '/diagnostics':
                msg = deserialize_message(message.data, DiagnosticArray)
                statuses |= {(s.name, s.hardware_id) for s in msg.status}
    return stamps, rows, size, statuses


# --- the tests -------------------------------------------------------------------------------

def test_the_skip_says_why(monkeypatch):
    """Without root or without ``ip``, the reason names what is missing (runs anywhere)."""
    if not sys.platform.startswith('linux'):
        assert 'Linux only' in netns_hosts.unavailable_reason()
        return
    monkeypatch.setattr(netns_hosts.os, 'geteuid', lambda: 1000)
    assert netns_hosts.unavailable_reason() == (
        'creating network namespaces needs root (ip netns add)')
    monkeypatch.setattr(netns_hosts.os, 'geteuid', lambda: 0)
    monkeypatch.setattr(netns_hosts.shutil, 'which', lambda tool: None)
    assert netns_hosts.unavailable_reason() == (
        'no `ip` command (iproute2 / util-linux) on PATH')


def test_subnet_reaches_the_other_host(runs):
    """SUBNET on both hosts: the recorder on B holds the node's batches at its rate and its
    /diagnostics status; the monitor on B reports A's accelerometer."""
    record = runs.tmp / 'b.mcap'
    before = runs.hosts.link_counters('b')
    runs.start('node', 'a', NODE, range='SUBNET')
    # namespaces: every one ('/'); unset, the recorder of this tree fails to read it
    runs.start('recorder', 'b', [BIN / 'impact_damper_recorder', '--ros-args',
                                 '-p', f'output:={record}', '-p', "namespaces:=['/']"],
               range='SUBNET')
    runs.start('monitor', 'b', [BIN / 'impact_damper_monitor'], range='SUBNET')
    runs.probe('probe_b', 'b', range='SUBNET')
    runs.wait_for_batches('probe_b')
    # the recorder finds new topics by polling the graph: on a slow or loaded machine it
    # subscribed to the batches seconds after the probe (122 of 300 recorded, once). Twice
    # ENOUGH after its subscription leaves it time to match the node's writer
    runs.wait_for_log('recorder', BATCH_TOPIC)
    runs.wait_for_batches('probe_b', 2 * ENOUGH)
    assert runs.stop('node') == [0], runs.log('node')
    assert runs.stop('recorder', 'monitor', 'probe_b') == [0, 0, 0], runs.log('recorder')
    crossed = runs.hosts.link_counters('b')['rx_bytes'] - before['rx_bytes']

    assert '/vibration_node' in runs.state('probe_b')['nodes']
    stamps, rows, size, statuses = read_mcap(record)
    assert len(stamps) >= ENOUGH, runs.log('recorder')
    span = stamps[-1] - stamps[0]                       # sim time the batches cover (s)
    expected = round(span / TICK_PERIOD) + 1            # one batch a tick, first to last
    # the node's rate: every batch (reliable QoS; 1 % missing allowed), each full
    assert expected * 0.99 <= len(stamps) <= expected, (len(stamps), expected)
    assert rows == [round(SAMPLE_RATE * TICK_PERIOD)] * len(stamps)
    assert (STATUS_NAME, 'sdof') in statuses, statuses
    # the batches' bytes came over host B's end of the link (UDP and IP headers on top)
    assert crossed >= size > 0, (crossed, size)
    print(f'host B recorded {len(stamps)} batches over {span:.2f} s of sim time (expected '
          f'{expected}), {sum(rows)} samples; its link received {crossed} bytes, the batches '
          f'are {size}')
    mon = runs.log('monitor')
    lines = [ln for ln in mon.splitlines() if 'accel/sdof_primary: rms' in ln]
    assert lines and '2000 samples/s' in lines[-1], mon[-2000:]


def test_localhost_stays_on_its_host(runs):
    """LOCALHOST on both hosts: a probe beside the node receives its batches; a probe on the
    other host at the same time receives nothing and does not see the node."""
    runs.start('node', 'a', NODE, range='LOCALHOST')
    runs.probe('probe_a', 'a', range='LOCALHOST')
    runs.probe('probe_b', 'b', range='LOCALHOST')
    runs.wait_for_batches('probe_a')
    assert runs.stop('node') == [0], runs.log('node')
    runs.stop('probe_a', 'probe_b')
    a, b = runs.state('probe_a'), runs.state('probe_b')
    assert a['batches'] >= ENOUGH and STATUS_NAME in a['statuses']
    assert '/vibration_node' in a['nodes']
    print(f"host A's probe: {a['batches']} batches, host B's: {b['batches']}; B's graph: "
          f"{b['nodes']}")
    assert b['batches'] == 0 and b['statuses'] == [], b
    assert '/vibration_node' not in b['nodes'], b


def test_static_peers_cross_a_router(routed_runs):
    """Two subnets and a router: multicast discovery stays on each subnet; a static peer on B
    naming A connects them (the node keeps the defaults)."""
    runs = routed_runs
    hosts = runs.hosts
    assert hosts.routed and hosts.addresses == {'a': '10.231.0.1', 'b': '10.231.1.2'}
    runs.start('node', 'a', NODE)                                    # ROS defaults
    runs.probe('peer_b', 'b', range='SUBNET', peers=hosts.addresses['a'])
    runs.probe('multicast_b', 'b', range='SUBNET')
    runs.wait_for_batches('peer_b')
    assert runs.stop('node') == [0], runs.log('node')
    runs.stop('peer_b', 'multicast_b')
    peer, multicast = runs.state('peer_b'), runs.state('multicast_b')
    assert peer['batches'] >= ENOUGH and STATUS_NAME in peer['statuses']
    print(f"B with the static peer: {peer['batches']} batches, without: "
          f"{multicast['batches']}; its graph: {multicast['nodes']}")
    assert multicast['batches'] == 0 and '/vibration_node' not in multicast['nodes'], multicast


@pytest.mark.slow
def test_a_static_peer_reaches_four_processes_of_a_host(routed_runs):
    """Fast DDS announces to a static peer's first four participants (SUBNET's
    maxInitialPeersRange): a node started as host A's fifth ROS process is not reached from B
    naming A; the same node naming B reaches it (docs/guides/across-hosts.md, the limit)."""
    runs = routed_runs
    a, b = runs.hosts.addresses['a'], runs.hosts.addresses['b']
    for i in range(4):                       # participants 0..3 of host A
        runs.probe(f'filler{i}', 'a')
    end = time.monotonic() + DEADLINE
    while not all((runs.tmp / f'filler{i}.json').exists() for i in range(4)):
        assert time.monotonic() < end, 'the four first processes of host A did not start'
        time.sleep(0.1)
    runs.start('node', 'a', NODE)            # the fifth
    runs.probe('peer_b', 'b', peers=a)
    runs.probe('beside', 'a')                # the node runs: a probe beside it counts
    runs.wait_for_batches('beside')
    assert runs.stop('node') == [0], runs.log('node')
    one_sided = runs.state('peer_b')
    print(f"fifth process, B names A: {one_sided['batches']} batches on B "
          f"({runs.state('beside')['batches']} beside the node on A)")
    assert one_sided['batches'] == 0 and '/vibration_node' not in one_sided['nodes']
    runs.start('node_naming_b', 'a', NODE, peers=b)
    runs.wait_for_batches('peer_b')          # fails (with the logs) if it never arrives
    assert runs.stop('node_naming_b') == [0]
    print(f"and naming B: {runs.state('peer_b')['batches']} batches on B")


if __name__ == '__main__':
    if sys.argv[1:2] == ['probe'] and len(sys.argv) == 3:
        sys.exit(probe_main(sys.argv[2]))
    sys.exit('usage: test_across_hosts.py probe OUT.json (run on a host by the tests)')
