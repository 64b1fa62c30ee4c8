"""``recorder``: one MCAP log of several machines (a plant's "one log for all").

Started by ``plant.launch.py`` when the plant file says ``record: one_log``, or by hand::

    ros2 run impact_damper_sim recorder --ros-args -p output:=plant.mcap \\
        -p plant:=ten_hpotp
    ros2 run impact_damper_sim recorder --ros-args -p output:=two.mcap \\
        -p namespaces:="[pump1, pump2]"

It subscribes, raw (the CDR bytes as they come: nothing is deserialized), to the topics of
each namespace that match ``topics`` (default: every accelerometer's ``accel/<name>`` Imu and
``accel/<name>/batch``, the ground truth, ``impacts``, ``impactor_state``, ``rotor/*`` and the
fault commands) and to ``/diagnostics``, as they appear in the ROS graph (polled every 0.1 s
for the first 30 s, then every 0.5 s), with each topic's publishers' reliability and
durability (keep last 1000). It writes them with the package's own writer
(:class:`~impact_damper_sim.recording.AsyncRecorder`, rosbag2's MCAP layout, the schemas
from the ament index, each topic's offered QoS), log time the arrival (ns since the epoch),
publish time the sender's source timestamp. The plant's labels (each machine's namespace,
scene, seed, unbalance, preset, faults, hardware_id) open the log as the metadata record
``impact_damper_sim_plant``.

SIGINT, SIGTERM or SIGHUP (Ctrl-C, ``ros2 launch``'s shutdown, a closed terminal) ends it
cleanly: what has arrived is taken, written and the file finished (summary and rosbag2
metadata) before it exits; it says how many messages it wrote. It waits on a wait set of its
own subscriptions, as the bench's raw reader does: rclpy's executor costs about 0.4 ms a
message in Python, and ten machines send some 11,000 messages a second. So it serves no
parameter services: its parameters are read once, at start.

Parameters: ``output`` (MCAP file; empty = ``./<plant or 'plant'>_<YYYYmmdd-HHMMSS>.mcap``),
``overwrite`` (replace an existing file), ``plant`` (plant name or file: the labels, and the
namespaces when ``namespaces`` is empty), ``namespaces`` (string array; empty = the plant's,
else every namespace), ``topics`` (string array of patterns relative to a namespace, ``*``
one name token), ``diagnostics`` (also record ``/diagnostics``).
"""
from __future__ import annotations

import fnmatch
import signal
import sys
import time

#: metadata record of the plant's labels
PLANT_METADATA = 'impact_damper_sim_plant'
#: topics recorded in each namespace: patterns of its relative names, ``*`` one token
DEFAULT_TOPICS = ('accel/*', 'accel/*/batch', 'accel/*/truth', 'impacts', 'impactor_state',
                  'rotor/*')
DIAGNOSTICS = '/diagnostics'
#: graph polls: every FAST_POLL s for the first FAST_SPAN s (a plant's nodes start over many
#: seconds on a small host: a slow poll then missed a node's first 90 ms), then SLOW_POLL s
FAST_POLL, FAST_SPAN, SLOW_POLL = 0.1, 30.0, 0.5
#: messages taken from one subscription per wake (the rest on the next, no starvation)
TAKE_PER_WAKE = 1000


def matches(topic, namespace, patterns):
    """Whether the fully qualified ``topic`` lies in ``namespace`` ('' or '/' = any) and its
    name there matches one of ``patterns`` (``*`` stands for one name token)."""
    prefix = '/' + namespace.strip('/')
    if prefix == '/':
        rel = topic.lstrip('/')
        # any namespace: the pattern matches the topic's last tokens
        tokens = rel.split('/')
        return any(len(tokens) >= len(p.split('/')) and all(
            fnmatch.fnmatchcase(t, q) for t, q in zip(tokens[-len(p.split('/')):],
                                                      p.split('/'))) for p in patterns)
    if not topic.startswith(prefix + '/'):
        return False
    tokens = topic[len(prefix) + 1:].split('/')
    return any(len(tokens) == len(p.split('/')) and all(
        fnmatch.fnmatchcase(t, q) for t, q in zip(tokens, p.split('/'))) for p in patterns)


def plant_metadata(plant=None, namespaces=()):
    """The :data:`PLANT_METADATA` record (str to str): the plant's name, file and seed, and
    its machines' labels (YAML), or the namespaces recorded when there is no plant file."""
    import yaml

    import impact_damper_sim
    out = {'software_version': impact_damper_sim.__version__,
           'namespaces': ', '.join(namespaces),
           'time_base': 'wall clock (log_time = arrival at the recorder, publish_time = the '
                        "sender's source timestamp), ns since the epoch"}
    if plant is not None:
        labels = plant.labels()
        out.update(plant=labels['plant'], source=labels['source'], seed=str(labels['seed']),
                   machines=yaml.safe_dump(labels['machines'], sort_keys=False))
    return out


class PlantRecorder:
    """Raw subscriptions to the namespaces' topics, written to one MCAP.

    Parameters
    ----------
    node : rclpy.node.Node
        The node that subscribes (its graph queries find the topics).
    output : str or os.PathLike
        MCAP file.
    namespaces : sequence of str
        Namespaces to record (``'/'`` = every one).
    topics : sequence of str
        Patterns of the topic names relative to a namespace.
    diagnostics : bool
        Also record ``/diagnostics``.
    metadata : dict of str to str
        Written as :data:`PLANT_METADATA` when the log opens.
    overwrite : bool
        Replace an existing file.

    Raises
    ------
    OSError
        The file cannot be made (one line, as the node's ``record`` says it).
    """

    def __init__(self, node, output, namespaces, topics=DEFAULT_TOPICS, diagnostics=True,
                 metadata=None, overwrite=False):
        from ..recording import AsyncRecorder
        from ..recording.node_topics import RECORD_CHUNK_SIZE
        self.node = node
        self.namespaces = [ns if ns.startswith('/') else '/' + ns for ns in namespaces] or ['/']
        self.patterns = tuple(topics)
        self.diagnostics = diagnostics
        self.recorder = AsyncRecorder(output, overwrite=overwrite, chunk_size=RECORD_CHUNK_SIZE,
                                      overwrite_option='overwrite:=true')
        self.path = self.recorder.path
        self.recorder.add_metadata(PLANT_METADATA, dict(metadata or {}))
        self.subs = []        # (subscription, topic, type name, offered QoS list)
        self.counts = {}      # topic -> messages taken
        self._wait_set, self._wait_size = None, 0
        self._started = time.monotonic()
        self._next_poll = 0.0

    def wanted(self, topic):
        """Whether ``topic`` (fully qualified) is one to record."""
        if topic == DIAGNOSTICS:
            return self.diagnostics
        return any(matches(topic, ns, self.patterns) for ns in self.namespaces)

    def discover(self):
        """Subscribe to every wanted topic that has a publisher and no subscription yet.

        Returns
        -------
        list of str
            The topics subscribed to now.
        """
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

        from ..studies.log_reader import LogError
        from .replay_plan import message_class
        new = []
        for topic, types in self.node.get_topic_names_and_types():
            if topic in self.counts or not types or not self.wanted(topic):
                continue
            infos = self.node.get_publishers_info_by_topic(topic)
            if not infos:   # a subscriber only (a command topic nobody sent yet)
                continue
            offered = [i.qos_profile for i in infos]
            qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000)
            # what every publisher offers: reliable / latched only if all are
            qos.reliability = (ReliabilityPolicy.RELIABLE if all(
                q.reliability == ReliabilityPolicy.RELIABLE for q in offered)
                else ReliabilityPolicy.BEST_EFFORT)
            qos.durability = (DurabilityPolicy.TRANSIENT_LOCAL if all(
                q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered)
                else DurabilityPolicy.VOLATILE)
            type_name = types[0]
            try:
                msg_type = message_class(type_name)
                self.recorder.add_topic(topic, type_name, offered)
            except (LogError, ValueError, LookupError, OSError) as exc:
                self.node.get_logger().warning(f'not recording {topic} ({type_name}): {exc}',
                                               once=True)
                self.counts[topic] = 0
                continue
            sub = self.node.create_subscription(msg_type, topic, lambda _: None, qos, raw=True)
            self.subs.append((sub, topic, type_name, offered))
            self.counts[topic] = 0
            new.append(topic)
        return new

    def spin_once(self, timeout=0.05):
        """Poll the graph when due, wait up to ``timeout`` (s) for messages and write what
        came. Returns the number of messages written."""
        now = time.monotonic()
        if now >= self._next_poll:
            new = self.discover()
            if new:
                self.node.get_logger().info(f'recording {len(new)} more topics '
                                            f'({len(self.subs)} in all): {", ".join(new)}')
            self._next_poll = now + (FAST_POLL if now - self._started < FAST_SPAN
                                     else SLOW_POLL)
        if not self.subs:
            time.sleep(timeout)
            return 0
        return self._take(timeout)

    def _take(self, timeout):
        from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
        if self._wait_size != len(self.subs):
            self._wait_set = _rclpy.WaitSet(len(self.subs), 0, 0, 0, 0, 0,
                                            self.node.context.handle)
            self._wait_size = len(self.subs)
        wait_set = self._wait_set
        wait_set.clear_entities()
        for sub, *_ in self.subs:
            wait_set.add_subscription(sub.handle)
        wait_set.wait(int(timeout * 1e9))
        ready = wait_set.get_ready_entities('subscription')
        write, n = self.recorder.write, 0
        for sub, topic, type_name, offered in self.subs:
            if sub.handle.pointer not in ready:
                continue
            k = 0
            with sub.handle:
                while k < TAKE_PER_WAKE:
                    got = sub.handle.take_message(sub.msg_type, True)
                    if got is None:
                        break
                    data, info = got
                    arrived = time.time_ns()
                    sent = info.get('source_timestamp') or arrived
                    write(topic, type_name, offered, data, arrived, sent)
                    k += 1
            self.counts[topic] += k
            n += k
        return n

    def take_all(self, rounds=20):
        """Take what every subscription holds now (after a stop): until a wait finds nothing."""
        total = 0
        for _ in range(rounds):
            n = self._take(0.0) if self.subs else 0
            total += n
            if n == 0:
                break
        return total

    def close(self):
        """Finish the file (drains the writer's queue); returns its stats (dict)."""
        stats = self.recorder.close()
        stats['topic_counts'] = self.recorder.topic_counts()   # written, after the drain
        return stats



def _declare(node):
    """Declare the recorder's parameters and return their values (dict)."""
    from rcl_interfaces.msg import ParameterDescriptor
    from rclpy.parameter import Parameter
    specs = {
        'output': ('', 'MCAP file; empty = ./<plant>_<YYYYmmdd-HHMMSS>.mcap'),
        'overwrite': (False, 'replace an existing file (otherwise refused)'),
        'plant': ('', 'plant name (config/plants) or file: labels, and the namespaces when '
                      'namespaces is empty'),
        'namespaces': (Parameter.Type.STRING_ARRAY, 'namespaces to record; empty = the '
                                                    "plant's, else every namespace"),
        'topics': (list(DEFAULT_TOPICS), 'patterns of topic names relative to a namespace '
                                         '(* = one name token)'),
        'diagnostics': (True, 'also record /diagnostics'),
    }
    values = {}
    for name, (default, description) in specs.items():
        node.declare_parameter(name, default, ParameterDescriptor(
            name=name, description=description, read_only=True))
        # a typed array without a default is uninitialised when not given: get_parameter
        # raises then, get_parameter_or gives the Parameter with value None
        value = node.get_parameter_or(name).value
        values[name] = list(value) if isinstance(value, (list, tuple)) else value
    values['namespaces'] = values['namespaces'] or []
    return values


def main(args=None):
    """Run the recorder until SIGINT or SIGTERM; finish the file; exit 0 (2: a usage or
    file error, one line on stderr)."""
    import datetime

    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from .._exit_status import EXIT_USAGE
    from ..scene.plant import load_plant
    from ..scene.schema import SceneError

    stop = []

    def on_signal(*_):
        stop.append(True)

    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGHUP, on_signal)   # a closed terminal ends it as SIGTERM does
    node = rclpy.create_node('recorder', start_parameter_services=False)
    log = node.get_logger()
    rec = None
    try:
        try:
            params = _declare(node)
            plant = load_plant(params['plant']) if params['plant'] else None
        except (SceneError, ValueError, TypeError) as exc:
            print(f'recorder: {exc}', file=sys.stderr)
            return EXIT_USAGE
        namespaces = params['namespaces'] or (plant.namespaces if plant else ['/'])
        output = params['output'] or datetime.datetime.now().strftime(
            f"{plant.name if plant else 'plant'}_%Y%m%d-%H%M%S.mcap")
        try:
            rec = PlantRecorder(node, output, namespaces, params['topics'],
                                params['diagnostics'], plant_metadata(plant, namespaces),
                                overwrite=params['overwrite'])
        except (OSError, ValueError) as exc:
            print(f'recorder: {exc}', file=sys.stderr)
            return EXIT_USAGE
        log.info(f"recording {', '.join(namespaces)} to {rec.path}")
        while not stop and rclpy.ok():
            rec.spin_once()
        rec.take_all()
        return 0
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)   # one stop; the clean-up runs whole
        if rec is not None:
            stats = rec.close()
            counts = stats['topic_counts']
            line = (f"recorded {stats['messages_written']:,} messages on {len(counts)} topics "
                    f'to {rec.path}')
            if stats['messages_dropped']:
                line += f" ({stats['messages_dropped']:,} dropped: the writer fell behind)"
            if stats['error']:
                log.error(f"recording {rec.path} ended unfinished: {stats['error']}; "
                          f'`study recover {rec.path} OUT.mcap` keeps what reached the disk')
            else:
                log.info(line)
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
