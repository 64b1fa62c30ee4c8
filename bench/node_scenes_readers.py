"""The reader processes of bench/node_scenes.py: the raw reader and the stock Python reader.

Two self-contained scripts, held as strings and run with ``python -c`` in processes of their own
(the bench starts one raw reader, one Python reader per Imu topic): what each reads, how it waits
and what it leaves behind are described in node_scenes.py's docstring. They are apart from the
bench's driver because they run in other processes: nothing here is called by the bench itself.
"""

# ---------------------------------------------------------------------------------------
#: the raw reader: every topic the node publishes, raw; JSON events on stdout; on SIGINT
#: writes <out>.npz (per-topic stamps, arrival times, samples) and <out>.json
RAW_READER = r'''
import importlib, json, signal, struct, sys, time
from array import array
import rclpy
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.qos import QoSProfile, HistoryPolicy, ReliabilityPolicy, DurabilityPolicy
from rclpy.serialization import deserialize_message
from rclpy.signals import SignalHandlerOptions

node_name, node_ns, out, domain, drain = (sys.argv[1], sys.argv[2], sys.argv[3],
                                          int(sys.argv[4]), sys.argv[5] == '1')
stop = False
def on_signal(*_):
    global stop
    stop = True
rclpy.init(domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
signal.signal(signal.SIGINT, on_signal)
signal.signal(signal.SIGTERM, on_signal)
# no parameter services, no rosout: the reader's wait set holds its subscriptions only
node = rclpy.create_node('bench_raw_reader', start_parameter_services=False,
                         enable_rosout=False)
now = time.monotonic
unpack = struct.unpack_from

def say(**kw):
    print(json.dumps(kw), flush=True)

def msg_class(type_name):
    pkg, _, name = type_name.split('/')
    return getattr(importlib.import_module(pkg + '.msg'), name)

def pc2_samples(data):
    e = '<' if data[1] == 1 else '>'
    n = unpack(e + 'I', data, 12)[0]          # header.frame_id length (with its NUL)
    off = 16 + n
    off += (-(off - 4)) % 4                   # CDR alignment counts from after the 4-byte header
    h, w = unpack(e + 'II', data, off)
    return h * w

topics = {}     # name -> record
diags = []      # (arrival, status name, level, message, values)
firsts = {}

class Rec:
    def __init__(self, name, type_name):
        self.name, self.type = name, type_name
        self.stamps, self.wall, self.samples = array('q'), array('d'), array('q')
        self.pc2 = type_name.endswith('/PointCloud2')
        self.diag = type_name.endswith('/DiagnosticArray')
        self.check = None
        self.cls = msg_class(type_name)
        self.bytes = 0

def handle(rec, data):
    t = now()
    sec, nsec = unpack('<iI' if data[1] == 1 else '>iI', data, 4)
    rec.stamps.append(sec * 1000000000 + nsec)
    rec.wall.append(t)
    rec.bytes += len(data)
    if rec.pc2:
        n = pc2_samples(data)
        rec.samples.append(n)
        if rec.check is None:
            m = deserialize_message(data, rec.cls)
            rec.check = 'ok' if m.width * m.height == n else (
                f'parsed {n}, deserialized {m.width * m.height}')
    if rec.diag:
        m = deserialize_message(data, rec.cls)
        for s in m.status:
            level = s.level if isinstance(s.level, int) else int.from_bytes(s.level, 'little')
            diags.append((t, s.name, level, s.message, {kv.key: kv.value for kv in s.values}))
            if s.name.endswith('/' + node_name + ': simulation') and 'diag' not in firsts:
                firsts['diag'] = t
                say(event='first_diag', t=t)
    elif rec.type in ('sensor_msgs/msg/Imu', 'sensor_msgs/msg/PointCloud2') \
            and 'sample' not in firsts:
        firsts['sample'] = t
        say(event='first_sample', t=t, topic=rec.name)

subs = []       # (subscription, record), in the wait set's order

def subscribe(name, type_name, infos):
    rec = Rec(name, type_name)
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000)
    if infos:
        qos.reliability = infos[0].qos_profile.reliability
        qos.durability = infos[0].qos_profile.durability
    sub = node.create_subscription(rec.cls, name, lambda _: None, qos, raw=True)
    subs.append((sub, rec))
    topics[name] = rec
    return rec

def take_ready(wait_set):
    """Take what each ready subscription holds (all of it with drain, else one message)."""
    ready = wait_set.get_ready_entities('subscription')
    for sub, rec in subs:
        if sub.handle.pointer in ready:
            with sub.handle:
                for _ in range(1000 if drain else 1):
                    got = sub.handle.take_message(sub.msg_type, True)
                    if got is None:
                        break
                    handle(rec, got[0])

graph_nodes = set()
monitor_subs = set()

def discover():
    try:
        graph_nodes.update(f'{ns.rstrip("/")}/{n}' for n, ns in
                           node.get_node_names_and_namespaces())
        monitor_subs.update(name for name, _ in
                            node.get_subscriber_names_and_types_by_node('monitor', node_ns))
    except Exception:
        pass
    try:
        found = node.get_publisher_names_and_types_by_node(node_name, node_ns)
    except Exception:   # the node is not in the graph (yet)
        return
    new = []
    for name, types in found:
        if name in topics or not types:
            continue
        try:
            subscribe(name, types[0], node.get_publishers_info_by_topic(name))
        except Exception as exc:
            say(event='error', topic=name, error=f'{type(exc).__name__}: {exc}')
            continue
        new.append([name, types[0]])
    if new:
        say(event='topics', t=now(), topics=new)

say(event='ready', t=now())
next_discovery = 0.0
settled = None    # 3 s after the node's own topics appeared: poll every 0.5 s, not 0.1 s
c0 = time.process_time()
t0 = now()
wait_set, wait_size = None, 0
while not stop:
    t = now()
    if t >= next_discovery:
        discover()
        if settled is None and any(n not in ('/rosout', '/parameter_events') for n in topics):
            settled = t + 3.0
        next_discovery = t + (0.5 if settled is not None and t > settled else 0.1)
    if not subs:
        time.sleep(0.05)
        continue
    # rclpy's executor rebuilds its wait set from every entity in Python for each message
    # (about 0.4 ms a message here, 68 % of a core at 1,500 messages/s); a wait set of the
    # subscriptions alone, drained on each wake, is what a lean C++ client does
    if len(subs) != wait_size:
        wait_set = _rclpy.WaitSet(len(subs), 0, 0, 0, 0, 0, node.context.handle)
        wait_size = len(subs)
    wait_set.clear_entities()
    for sub, _ in subs:
        wait_set.add_subscription(sub.handle)
    wait_set.wait(50_000_000)
    take_ready(wait_set)
t1 = now()
cpu = time.process_time() - c0
import numpy as np
arrays, meta = {}, []
for i, rec in enumerate(topics.values()):
    arrays[f's{i}'] = np.array(rec.stamps, dtype=np.int64)
    arrays[f'w{i}'] = np.array(rec.wall, dtype=float)
    arrays[f'n{i}'] = np.array(rec.samples, dtype=np.int64)
    meta.append({'topic': rec.name, 'type': rec.type, 'index': i, 'bytes': rec.bytes,
                 'width_check': rec.check})
np.savez(out + '.npz', **arrays)
with open(out + '.json', 'w') as f:
    json.dump({'topics': meta, 'diagnostics': diags, 'cpu_s': cpu, 'wall_s': t1 - t0,
               'drain': drain, 'graph_nodes': sorted(graph_nodes),
               'monitor_subscriptions': sorted(monitor_subs)}, f)
say(event='done')
node.destroy_node()
rclpy.try_shutdown()
'''

#: a stock Python reader: imports and init first, then waits for its topic on stdin
PY_READER = r'''
import json, signal, sys, time
from array import array
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import qos_profile_sensor_data
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import Imu

index, out, domain = sys.argv[1], sys.argv[2], int(sys.argv[3])
stop = started = False
def on_signal(*_):
    global stop
    stop = True
    if not started:
        raise KeyboardInterrupt
signal.signal(signal.SIGINT, on_signal)
signal.signal(signal.SIGTERM, on_signal)
try:
    rclpy.init(domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('bench_python_reader_' + index)   # discovered before the topic
    print('warm', flush=True)
    topic = sys.stdin.readline().strip()
except KeyboardInterrupt:
    sys.exit(0)
if not topic:
    sys.exit(0)
started = True
stamps, wall = array('q'), array('d')
now = time.monotonic

def on_sample(msg):
    s = msg.header.stamp
    stamps.append(s.sec * 1000000000 + s.nanosec)
    wall.append(now())

node.create_subscription(Imu, topic, on_sample, qos_profile_sensor_data)
ex = SingleThreadedExecutor()
ex.add_node(node)
print('ready', flush=True)
c0, t0 = time.process_time(), now()
while not stop:
    ex.spin_once(timeout_sec=0.1)
cpu, t1 = time.process_time() - c0, now()
with open(out + '.stamps', 'wb') as f:
    stamps.tofile(f)
with open(out + '.wall', 'wb') as f:
    wall.tofile(f)
print(json.dumps({'topic': topic, 'received': len(stamps), 'cpu_s': cpu, 'wall_s': t1 - t0}),
      flush=True)
node.destroy_node()
rclpy.try_shutdown()
'''
