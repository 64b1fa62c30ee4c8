"""A plant on one host: N ``vibration_node`` processes, a raw subscriber on every batch topic.

Issue 39 item 3. The machines are N copies of one scene (``--scene hpotp --n 10``: namespaces
``m01`` ... ``m10``, noise seeds 1 ... N) or a plant file (``--plant ten_hpotp``, the machines
and parameters ``plant.launch.py`` would start: :meth:`Machine.node_parameters`, ``/clock``
from the first one only). Each node runs as users start it (``.venv/bin/vibration_node
--ros-args -r __ns:=/<ns> --params-file <its parameters>``) in its own process, all in one
DDS domain of this host (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``), with one more process:

* **a raw reader** of every ``/<ns>/accel/<name>/batch`` topic (``sensor_msgs/PointCloud2``,
  the full-rate samples; found in the graph, polled every 0.1 s, then 0.5 s) and of
  ``/diagnostics``. It subscribes with ``raw=True`` (nothing deserialized: the sample count
  ``height x width`` is read from the CDR bytes), reliable, keep last 1000, and waits on a wait
  set of its own subscriptions, draining each on a wake (the lean client of
  bench/node_scenes.py's raw reader, which reads every topic of one node: this one reads the
  batch topics of all of them). It keeps each batch's header stamp and sample count, and
  each node's ``/diagnostics`` status (deserialized, 1 Hz a node).

The run lasts ``--seconds`` from the moment every machine has delivered its first batch (the
start column: from the spawn of the nodes to then; N nodes start at once on 2 cores, and with
``--stagger S``, default the plant file's ``stagger``, machine i's rotor runs up i x S s after
machine 0's, as a plant's pumps are started). Each machine is judged from its own first
batch. Then the reader and the nodes get SIGINT. What is measured, per machine:

* **delivered/expected per 1 s window**: the node's own ``/diagnostics`` windows (period 1 s
  of wall time; ``sim_time_s`` at each) give each window's span of sim time; delivered is
  the samples the reader got whose times lie in that span (per accelerometer; a batch's
  samples are at its stamp + k / rate, so a batch across a window's edge is split exactly),
  divided by the samples the node counted in it
  (``samples_per_s`` x span), times the window's ``real_time_factor_achieved``: samples
  delivered per wall second over samples a real-time DAQ delivers, so a node behind real
  time and a reader that lost samples both lower it. The worst accelerometer counts. The
  first window (the start) is left out. **worst** and **median** over the windows.
* **CPU** of the node's process (utime + stime from ``/proc``, every 1 s, % of one core:
  median of the 1 s windows) and the reader's; the machine's total.
* **RSS** of the node's process at the end (``VmRSS``) and its peak (``VmHWM``), MB.

With ``--hosts K`` the machines run in K ``plant_host`` processes (``--share 0/K`` ...
``K-1/K`` of one plant file: the ``--plant`` file, or one written for the ``--scene`` copies
with their seeds and stagger; ``--stepping``, default shared: one stepping thread per
process), not one ``vibration_node`` each; a machine's CPU and memory are then its process's
divided by the machines in it.

A plant **holds** when every machine's worst window is >= 0.98. ``--ceiling SCENE`` runs N = 1,
2, 3, 5, 8, 10, 13, 16, ... copies of the scene until one does not hold (or ``--max-n``); the
ceiling is the largest N that held; ``--start-n``/``--max-n`` or ``--ns 6,7`` split a search
over several short runs (the page merges them). ``--page`` adds the run to
docs/bench/plant.md (the page keeps every result it was given, newest per label, as JSON in
a comment at its end, and is rewritten whole: date and machine once in the header).

Usage (quote figures only from a quiet machine: ``flock -x /tmp/bench.lock``)::

    .venv/bin/python bench/plant.py --plant ten_hpotp --seconds 20 --page
    .venv/bin/python bench/plant.py --plant mixed --page
    .venv/bin/python bench/plant.py --ceiling rbs --seconds 15 --page
    .venv/bin/python bench/plant.py --scene hpotp --n 3
    .venv/bin/python bench/plant.py --plant ten_hpotp --hosts 2 --page
"""
from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import queue
import re
import shlex
import signal
import sys
import tempfile
import time

import numpy as np
import yaml

from node_scenes import NODE_EXE, ROOT, VENV, base_env
from node_scenes_figures import machine
from node_scenes_procs import Child, CpuSampler, pick_domain, settled_script

#: a window holds at this delivered/expected
HOLD = 0.98
#: the N the ceiling search tries, then every 3 more
CEILING_NS = (1, 2, 3, 5, 8, 10)
PAGE = os.path.join(ROOT, 'docs', 'bench', 'plant.md')
HOST_EXE = os.path.join(VENV, 'bin', 'impact_damper_plant_host')
DATA_MARK = '<!-- plant-bench-data '

# ---------------------------------------------------------------------------------------
#: the reader: every /<ns>/accel/*/batch topic of the namespaces given, and /diagnostics;
#: argv: out path, domain, comma-separated namespaces. JSON events on stdout; on SIGINT
#: writes <out>.npz (per topic stamps, samples, arrivals) and <out>.json
READER = r'''
import json, signal, struct, sys, time
from array import array
import rclpy
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.qos import QoSProfile, HistoryPolicy, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rclpy.signals import SignalHandlerOptions
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import PointCloud2

out, domain, namespaces = sys.argv[1], int(sys.argv[2]), sys.argv[3].split(',')
stop = False
def on_signal(*_):
    global stop
    stop = True
rclpy.init(domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
signal.signal(signal.SIGINT, on_signal)
signal.signal(signal.SIGTERM, on_signal)
node = rclpy.create_node('plant_bench_reader', start_parameter_services=False,
                         enable_rosout=False)
now = time.monotonic
unpack = struct.unpack_from
prefixes = tuple('/' + ns.strip('/') + '/accel/' for ns in namespaces)

def say(**kw):
    print(json.dumps(kw), flush=True)

def samples_of(data):
    # PointCloud2 CDR: header stamp (8), frame_id (len + chars), then height and width
    e = '<' if data[1] == 1 else '>'
    n = unpack(e + 'I', data, 12)[0]
    off = 16 + n
    off += (-(off - 4)) % 4
    h, w = unpack(e + 'II', data, off)
    return h * w

class Rec:
    def __init__(self, name):
        self.name = name
        self.stamps, self.samples, self.wall = array('q'), array('q'), array('d')
        self.check = None

recs, subs, diags, firsts = {}, [], [], set()
qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                 reliability=ReliabilityPolicy.RELIABLE)

def discover():
    new = []
    for name, types in node.get_topic_names_and_types():
        if name in recs or not types:
            continue
        if name == '/diagnostics':
            rec = Rec(name)
            sub = node.create_subscription(DiagnosticArray, name, lambda _: None, qos, raw=True)
        elif name.startswith(prefixes) and name.endswith('/batch') \
                and types[0] == 'sensor_msgs/msg/PointCloud2' and name.count('/') == \
                [p for p in prefixes if name.startswith(p)][0].count('/') + 1:
            rec = Rec(name)
            sub = node.create_subscription(PointCloud2, name, lambda _: None, qos, raw=True)
        else:
            continue
        recs[name] = rec
        subs.append((sub, rec))
        new.append(name)
    if new:
        say(event='topics', t=now(), topics=new)

def handle(rec, data):
    t = now()
    if rec.name == '/diagnostics':
        m = deserialize_message(data, DiagnosticArray)
        for s in m.status:
            if s.name.endswith('/vibration_node: simulation'):
                diags.append((t, s.name, {kv.key: kv.value for kv in s.values}))
        return
    sec, nsec = unpack('<iI' if data[1] == 1 else '>iI', data, 4)
    n = samples_of(data)
    if rec.check is None:
        m = deserialize_message(data, PointCloud2)
        rec.check = 'ok' if m.width * m.height == n else f'parsed {n}, read {m.width * m.height}'
    rec.stamps.append(sec * 1000000000 + nsec)
    rec.samples.append(n)
    rec.wall.append(t)
    ns = rec.name.split('/accel/')[0]
    if ns not in firsts:
        firsts.add(ns)
        say(event='first', t=t, namespace=ns)

say(event='ready', t=now())
next_poll, t0 = 0.0, now()
wait_set, size = None, 0
c0 = time.process_time()
while not stop:
    t = now()
    if t >= next_poll:
        discover()
        next_poll = t + (0.1 if t - t0 < 10.0 else 0.5)
    if not subs:
        time.sleep(0.05)
        continue
    if len(subs) != size:
        wait_set = _rclpy.WaitSet(len(subs), 0, 0, 0, 0, 0, node.context.handle)
        size = len(subs)
    wait_set.clear_entities()
    for sub, _ in subs:
        wait_set.add_subscription(sub.handle)
    wait_set.wait(50_000_000)
    ready = wait_set.get_ready_entities('subscription')
    for sub, rec in subs:
        if sub.handle.pointer in ready:
            with sub.handle:
                for _ in range(1000):
                    got = sub.handle.take_message(sub.msg_type, True)
                    if got is None:
                        break
                    handle(rec, got[0])
cpu = time.process_time() - c0
import numpy as np
arrays, meta = {}, []
for i, rec in enumerate(r for r in recs.values() if r.name != '/diagnostics'):
    arrays[f's{i}'] = np.array(rec.stamps, dtype=np.int64)
    arrays[f'n{i}'] = np.array(rec.samples, dtype=np.int64)
    arrays[f'w{i}'] = np.array(rec.wall, dtype=float)
    meta.append({'topic': rec.name, 'index': i, 'check': rec.check})
np.savez(out + '.npz', **arrays)
with open(out + '.json', 'w') as f:
    json.dump({'topics': meta, 'diagnostics': diags, 'cpu_s': cpu, 'wall_s': now() - t0}, f)
say(event='done')
node.destroy_node()
rclpy.try_shutdown()
'''


# ---------------------------------------------------------------------------------------
def scene_machines(scene, n, stagger=0.0):
    """N copies of ``scene``: [(namespace, scene name, node parameters)], seeds 1..N; with
    ``stagger`` (s) machine i's rotor runs up i x it after machine 0's, as a plant file's
    ``stagger`` makes it (the schedule :meth:`Plant.node_parameters` writes)."""
    machines = [(f'm{i + 1:02d}', scene, {'scene': scene, 'noise_seed': i + 1})
                for i in range(n)]
    if not stagger:
        return machines
    sys.path.insert(0, ROOT)
    from impact_damper_sim.scene.plant import load_plant
    tmp = tempfile.mkdtemp(prefix='plant_bench_')
    path = write_copies_plant(machines, stagger, os.path.join(tmp, 'copies.yaml'))
    params = load_plant(path).node_parameters(schedule_dir=tmp)
    return [(ns, sc, dict(p, **{k: v for k, v in params[ns].items() if k == 'schedule'}))
            for ns, sc, p in machines]


def write_copies_plant(machines, stagger, path):
    """Write a plant file of the copies ``machines`` ([(namespace, scene, parameters)]:
    each one's namespace, scene and ``noise_seed``) whose rotors run up ``stagger`` s apart;
    returns ``path``."""
    with open(path, 'w') as f:
        yaml.safe_dump({'stagger': f'{float(stagger or 0.0)!r} s', 'machines': [
            {'namespace': ns, 'scene': scene, 'seed': int(params['noise_seed'])}
            for ns, scene, params in machines]}, f)
    return path


def plant_machines(name, stagger=None):
    """The machines of a plant file: [(namespace, scene name, node parameters)], the
    plant's name and its stagger (s; ``stagger`` overrides the file's), its logs off (a bench
    measures the plant, not its disk)."""
    sys.path.insert(0, ROOT)
    from impact_damper_sim.scene.plant import load_plant
    plant = load_plant(name)
    if stagger is not None:
        plant = plant.with_stagger(stagger, f'--stagger {stagger:g}')
    params = plant.node_parameters(schedule_dir=tempfile.mkdtemp(prefix='plant_bench_'))
    out = []
    for m in plant.machines:
        p = {k: v for k, v in params[m.namespace].items()
             if k not in ('record', 'record_overwrite')}
        out.append((m.namespace, m.scene_name, p))
    return out, plant.name, plant.stagger


def _rss_mb(pid):
    """(VmRSS, VmHWM) of a process (MB), NaN when gone."""
    got = {}
    try:
        with open(f'/proc/{pid}/status') as f:
            for line in f:
                if line.startswith(('VmRSS:', 'VmHWM:')):
                    key, value = line.split(':', 1)
                    got[key] = int(value.split()[0]) / 1024.0
    except OSError:
        pass
    return got.get('VmRSS', math.nan), got.get('VmHWM', math.nan)


def _float(text):
    try:
        return float(text)
    except (TypeError, ValueError):
        return math.nan


def machine_windows(diags, status, t_lo, t_hi):
    """The node's diagnostics windows received in [t_lo, t_hi] (dicts, in order)."""
    return [dict({k: _float(v) for k, v in values.items()}, arrival=t)
            for t, name, values in diags if name == status and t_lo <= t <= t_hi]


def samples_in(stamps_ns, counts, lo, hi, rate):
    """Samples of the batches (``stamps_ns``: each one's first sample, ``counts`` samples
    at ``rate`` Hz) whose times lie in (lo, hi] (sim s), to half a sample."""
    s = stamps_ns * 1e-9

    def upto(x):   # per batch: its samples at times <= x
        return np.clip(np.floor((x - s) * rate + 0.5) + 1, 0, counts)
    return int((upto(hi) - upto(lo)).sum())


def window_ratios(windows, topics):
    """delivered/expected per window (module notes): [(ratio, rtf, delivered fraction)],
    one per pair of consecutive windows inside every topic's received span; ``topics``:
    [(stamps ns, samples)] per accelerometer batch topic."""
    out = []
    for a, b in zip(windows, windows[1:]):
        lo, hi = a.get('sim_time_s', math.nan), b.get('sim_time_s', math.nan)
        sps = b.get('samples_per_s', math.nan)
        rtf = b.get('real_time_factor_achieved', math.nan)
        if not (hi > lo) or not sps > 0 or not topics:
            continue
        sent = sps * (hi - lo)
        spans = [(st.min() * 1e-9, st.max() * 1e-9 + n[-1] / sps) for st, n in topics
                 if st.size]
        if len(spans) < len(topics) or any(lo < first or hi > last for first, last in spans):
            continue   # the subscriber's span does not cover the window: not judged
        worst = min(samples_in(st, n, lo, hi, sps) / sent for st, n in topics)
        out.append((worst * rtf, rtf, worst))
    return out


def host_plant_file(machines, log_dir, plant=None, stagger=None):
    """The plant file ``plant_host --plant`` runs (its ``--share`` then splits it), as
    plant_host arguments: ``plant`` (a plant file's name or path) with ``stagger`` (s) as its
    override when given; else a plant file of the copies ``machines`` written in ``log_dir``
    (:func:`write_copies_plant`, ``stagger`` s apart)."""
    if plant is not None:
        return ['--plant', plant] + ([] if stagger is None else ['--stagger', repr(stagger)])
    return ['--plant', write_copies_plant(machines, stagger,
                                          os.path.join(log_dir, 'hosts_plant.yaml'))]


def run_plant(label, machines, args, domain, log_dir, plant=None, stagger=None):
    """Run the machines; a dict of figures per machine and for the plant. ``plant`` and
    ``stagger``: what :func:`host_plant_file` gives ``plant_host`` with ``--hosts``."""
    env = dict(base_env(), ROS_DOMAIN_ID=str(domain))
    res = {'label': label, 'n': len(machines), 'domain': domain,
           'scenes': sorted({s for _, s, _ in machines}), 'status': 'error', 'reason': ''}
    node_exe = settled_script([NODE_EXE])
    if node_exe is None:
        res['reason'] = f'{NODE_EXE} missing'
        return res
    children, nodes = [], []
    cpu = CpuSampler(1.0)
    out = os.path.join(log_dir, 'reader')
    namespaces = [ns for ns, _, _ in machines]
    try:
        reader = Child('reader', [sys.executable, '-c', READER, out, str(domain),
                                  ','.join(namespaces)], env, log_dir)
        children.append(reader)
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline:
            try:
                line = reader.get(1.0)
            except queue.Empty:
                continue
            if line is None or '"ready"' in line:
                break
        if args.hosts:
            host_exe = settled_script([HOST_EXE])
            if host_exe is None:
                res['reason'] = f'{HOST_EXE} missing'
                return res
            source = host_plant_file(machines, log_dir, plant, stagger)
            for h in range(args.hosts):
                c = Child(f'plant_host{h}', [
                    host_exe, *source, '--share', f'{h}/{args.hosts}',
                    '--record-mode', 'none', '--stepping', args.stepping], env, log_dir,
                    pipe=False)
                children.append(c)
                nodes.extend((ns, c) for ns in namespaces[h::args.hosts])
                cpu.add(c.pid)
                if h == 0:
                    cpu.add(reader.pid)
                    cpu.add('all')
        for i, (ns, _scene, params) in enumerate([] if args.hosts else machines):
            pfile = os.path.join(log_dir, f'{ns.replace("/", ".")}.yaml')
            with open(pfile, 'w') as f:
                yaml.safe_dump({'/**': {'ros__parameters': dict(
                    params, publish_clock=(i == 0))}}, f)
            c = Child(f'node_{ns.replace("/", ".")}', [
                node_exe, '--ros-args', '-r', f'__ns:=/{ns}', '--params-file', pfile],
                env, log_dir, pipe=False)
            children.append(c)
            nodes.append((ns, c))
            cpu.add(c.pid)
            if i == 0:
                cpu.add(reader.pid)
                cpu.add('all')
        t_spawn = min(c.t_spawn for _, c in nodes)
        # machines per process: a plant_host's CPU and memory are its machines' together
        sharing = {c.pid: sum(1 for _, d in nodes if d is c) for _, c in nodes}
        firsts = {}
        hard = t_spawn + args.start_timeout
        while len(firsts) < len(machines) and time.monotonic() < hard:
            try:
                line = reader.get(0.2)
            except queue.Empty:
                line = ''
            if line and line.startswith('{'):
                ev = json.loads(line)
                if ev.get('event') == 'first':
                    firsts[ev['namespace'].strip('/')] = ev['t']
            dead = [ns for ns, c in nodes if c.proc.poll() is not None]
            if dead:
                res['reason'] = f'node {dead[0]} exited at start: ' + ' | '.join(
                    [x for x in dict(nodes)[dead[0]].stderr_lines() if x.strip()][-2:])
                return res
        if len(firsts) < len(machines):
            res['reason'] = (f'{len(machines) - len(firsts)} of {len(machines)} machines '
                             f'published no batch within {args.start_timeout:g} s')
            return res
        t_first = max(firsts.values())
        res['start_s'] = t_first - t_spawn
        while time.monotonic() < t_first + args.seconds:
            try:
                reader.get(0.5)
            except queue.Empty:
                pass
        t_stop = time.monotonic()
        rss = {ns: _rss_mb(c.pid) for ns, c in nodes}
        exited = {ns: c.proc.poll() for ns, c in nodes if c.proc.poll() is not None}
        reader.signal()
        reader_rc = reader.wait(30.0)
        processes = list({id(c): c for _, c in nodes}.values())
        for c in processes:
            c.signal()
        for c in processes:
            c.wait(20.0)
        try:
            with open(out + '.json') as f:
                meta = json.load(f)
            arrays = np.load(out + '.npz')
        except (OSError, ValueError) as exc:
            res['reason'] = f'reader left no results ({exc}; exit {reader_rc})'
            return res
        res.update(status='ran', seconds=t_stop - t_first)
        _, res['machine_cpu_percent'] = cpu.windows('all', t_first, t_stop)
        # the start-up: the machine's busy cores and each node's CPU per 1 s from the spawn,
        # and when each machine's first batch arrived (s after the spawn)
        res['machine_cpu_from_spawn'] = [round(v) for v in cpu.windows('all', t_spawn,
                                                                        t_stop)[0]]
        _, res['reader_cpu_percent'] = cpu.windows(reader.pid, t_first, t_stop)
        topics = {}
        for m in meta['topics']:
            ns = m['topic'].split('/accel/')[0].strip('/')
            topics.setdefault(ns, []).append((arrays[f's{m["index"]}'],
                                              arrays[f'n{m["index"]}']))
        res['checks'] = sorted({m['check'] for m in meta['topics']} - {'ok'})
        per = []
        for (ns, scene, _), (_, c) in zip(machines, nodes):
            # every window of the machine from its own first batch (with a stagger the first
            # machines run long before the last one's first batch)
            windows = machine_windows(meta['diagnostics'], f'/{ns}/vibration_node: simulation',
                                      firsts[ns], t_stop + 1.0)
            ratios = window_ratios(windows, topics.get(ns, []))
            values = [r for r, _, _ in ratios]
            cpu_windows, cpu_mean = cpu.windows(c.pid, firsts[ns], t_stop)
            k = sharing[c.pid]   # a plant_host's machines share its CPU and memory
            cpu_windows = [v / k for v in cpu_windows]
            cpu_mean = cpu_mean / k if cpu_mean == cpu_mean else cpu_mean
            per.append({
                'namespace': ns, 'scene': scene, 'windows': len(values),
                'series': [round(v, 3) for v in values],   # the windows in time order
                # seconds after this machine's first batch at which the worst window ends
                # (the first window is left out: the series starts at 2)
                'worst_at_s': (int(np.argmin(values)) + 2) if values else None,
                'worst': min(values) if values else math.nan,
                'median': float(np.median(values)) if values else math.nan,
                'worst_rtf': min((r for _, r, _ in ratios), default=math.nan),
                'worst_delivery': min((d for _, _, d in ratios), default=math.nan),
                'cpu_percent': float(np.median(cpu_windows)) if cpu_windows else math.nan,
                'cpu_mean': cpu_mean,
                'first_batch_s': round(firsts[ns] - t_spawn, 2),
                'cpu_from_spawn': [round(v / k) for v in cpu.windows(c.pid, t_spawn,
                                                                       t_stop)[0]],
                'rss_mb': rss[ns][0] / k, 'hwm_mb': rss[ns][1] / k, 'per_process': k,
                'exited': exited.get(ns)})
        res['machines'] = per
        res['plant_cpu_percent'] = plant_cpu(res)
        worst = [m['worst'] for m in per]
        res['worst'] = min(worst) if worst else math.nan
        res['median'] = float(np.median([m['median'] for m in per]))
        res['holds'] = bool(per) and all(w >= HOLD for w in worst) and not exited
        return res
    finally:
        for c in children:
            if c.proc.poll() is None:
                c.proc.kill()
                try:
                    c.proc.wait(timeout=5.0)
                except Exception:
                    pass
        cpu.stop()


# ---------------------------------------------------------------------------------------
def plant_cpu(res):
    """CPU of the plant's processes, % of one core: the nodes' means over the measured span
    (their medians for a result without them) plus the subscriber's."""
    parts = [m.get('cpu_mean', m['cpu_percent']) for m in res['machines']]
    parts.append(res.get('reader_cpu_percent'))
    parts = [x for x in parts if x is not None and x == x]
    return float(sum(parts)) if parts else math.nan


def _f(x, fmt):
    return '-' if x is None or x != x else f'{x:{fmt}}'


def print_run(res):
    head = f'{res["label"]}: N = {res["n"]} ({", ".join(res["scenes"])})'
    if res['status'] != 'ran':
        print(f'{head}: {res["status"]}: {res["reason"]}', flush=True)
        return
    print(f'{head}: {"HOLDS" if res["holds"] else "does NOT hold"} (>= {HOLD} in every 1 s '
          f'window); worst window {_f(res["worst"], ".3f")}, start {res["start_s"]:.1f} s, '
          f'{res["seconds"]:.0f} s measured; plant CPU {_f(res["plant_cpu_percent"], ".0f")} '
          f'% of one core (subscriber {_f(res["reader_cpu_percent"], ".0f")} %), machine '
          f'{_f(res["machine_cpu_percent"], ".0f")} %', flush=True)
    print(f'  {"machine":10s} {"scene":10s} {"windows":>7s} {"worst":>6s} {"median":>6s} '
          f'{"rtf":>6s} {"deliv":>6s} {"CPU %":>6s} {"RSS MB":>7s} {"peak MB":>7s}')
    for m in res['machines']:
        print(f'  {m["namespace"]:10s} {m["scene"]:10s} {m["windows"]:7d} '
              f'{_f(m["worst"], "6.3f")} {_f(m["median"], "6.3f")} '
              f'{_f(m["worst_rtf"], "6.3f")} {_f(m["worst_delivery"], "6.3f")} '
              f'{_f(m["cpu_percent"], "6.1f")} {_f(m["rss_mb"], "7.0f")} '
              f'{_f(m["hwm_mb"], "7.0f")}' + (f'  exited {m["exited"]}' if m['exited']
                                               is not None else ''))
    if res.get('checks'):
        print(f'  sample-count parse disagreed with rclpy: {res["checks"]}')


# ---------------------------------------------------------------------------------------
def _load_page_data(path):
    try:
        with open(path) as f:
            text = f.read()
    except OSError:
        return {'runs': {}, 'ceilings': {}}
    match = re.search(re.escape(DATA_MARK) + r'(.*?) -->', text, re.S)
    return json.loads(match.group(1)) if match else {'runs': {}, 'ceilings': {}}


def _jsonable(x):
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return None if x != x else round(float(x), 4)
    if isinstance(x, np.integer):
        return int(x)
    return x


def _median(values):
    v = [x for x in values if x is not None and x == x]
    return float(np.median(v)) if v else None


def page(data):
    """The markdown page of every run kept in ``data`` (module notes)."""
    def g(x, fmt):
        return '-' if x is None else f'{x:{fmt}}'

    dates = sorted({r['date'] for r in data['runs'].values()}
                   | {c['date'] for c in data['ceilings'].values()})
    lines = [
        '# A plant on one host: measured',
        '',
        '<!-- written by bench/plant.py --page; do not edit: run it again -->',
        '',
        f'- **Date**: {" to ".join(dict.fromkeys([dates[0], dates[-1]])) if dates else "-"}',
        f'- **Machine**: {data.get("machine", "-")}',
        '- **What**: N `vibration_node` processes (one per machine, each in its namespace, '
        'real time), one raw subscriber on every `accel/<name>/batch` topic; a plant holds '
        f'when every machine delivers >= {HOLD} of its samples in every 1 s window '
        '(delivered/expected: the samples of the window that reached the subscriber, per '
        "wall second, over the sample rate; how, in `bench/plant.py`'s docstring). A plant "
        'marked `[K plant_host]` ran its machines in K `plant_host` processes instead '
        '(`--hosts K`: `--share 0/K` ... `K-1/K` of one plant file, one stepping thread per '
        'process; `, a thread per machine`: `--stepping own`).',
        '',
        '## Plants',
        '',
        '| plant | N | scenes | holds | worst window | median window | node CPU, median '
        '% of a core | node RSS, MB | plant CPU % | load before | start s | command |',
        '|---|---|---|---|---|---|---|---|---|---|---|---|',
    ]
    for label, r in data['runs'].items():
        if r['status'] != 'ran':
            lines.append(f'| {label} | {r["n"]} | {", ".join(r["scenes"])} | '
                         f'{r["status"]}: {r["reason"]} | | | | | | | | `{r["command"]}` |')
            continue
        ms = r['machines']
        lines.append(
            f'| {label} | {r["n"]} | {", ".join(r["scenes"])} | '
            f'{"yes" if r["holds"] else "**no**"} | {g(r["worst"], ".3f")} | '
            f'{g(r["median"], ".3f")} | {g(_median(m["cpu_percent"] for m in ms), ".0f")} | '
            f'{g(_median(m["rss_mb"] for m in ms), ".0f")} | '
            f'{g(plant_cpu(r), ".0f")} | {g(r.get("load_before"), ".2f")} | '
            f'{g(r["start_s"], ".0f")} | '
            f'`{r["command"]}` |')
    lines += ['', '## Ceilings: the largest N copies of one scene that hold', '',
              '| scene | ceiling N | tried: N (worst window) | command |', '|---|---|---|---|']
    for scene, c in data['ceilings'].items():
        tried = ', '.join(f'{t["n"]} ({g(t["worst"], ".3f")})' for t in c['tried'])
        lines.append(f'| {scene} | {c["ceiling"] if c["ceiling"] else "none"} | {tried} | '
                     f'`{c["command"]}` |')
    lines += ['', '## Per machine', '']
    for label, r in data['runs'].items():
        if r['status'] != 'ran':
            continue
        lines += [f'**{label}** (N = {r["n"]}):', '',
                  '| machine | scene | worst | worst at s | median | worst RTF | worst delivery | '
                  'CPU % | RSS MB | peak RSS MB |', '|---|---|---|---|---|---|---|---|---|---|']
        for m in r['machines']:
            lines.append(f'| {m["namespace"]} | {m["scene"]} | {g(m["worst"], ".3f")} | '
                         f'{g(m.get("worst_at_s"), "d")} | '
                         f'{g(m["median"], ".3f")} | {g(m["worst_rtf"], ".3f")} | '
                         f'{g(m["worst_delivery"], ".3f")} | {g(m["cpu_percent"], ".0f")} | '
                         f'{g(m["rss_mb"], ".0f")} | {g(m["hwm_mb"], ".0f")} |')
        lines.append('')
    lines += [
        '## What the columns mean', '',
        '- **worst / median window**: delivered/expected of the 1 s windows (the first, the '
        'start, left out); per machine the worst accelerometer; for a plant the worst '
        'machine, and the median of the machines\' medians.',
        '- **worst at s**: when the worst window ended, in seconds after the machine\'s '
        'own first batch (2 = the first window judged: start-up transients land there).',
        "- **worst RTF**: the node's own `real_time_factor_achieved`, its worst window; "
        '**worst delivery**: the worst window\'s share of the samples it published that '
        'reached the subscriber. The window figure is about their product.',
        '- **node CPU**: utime + stime of the node\'s process, median of its 1 s windows, % '
        'of one core; **plant CPU**: the nodes\' and the subscriber\'s processes over the '
        'measured span, % of one core (200 = both cores of this machine).',
        '- **node RSS**: resident memory at the end of the run; **peak**: `VmHWM`. In a '
        '`plant_host` row both node columns are its process\'s divided by its machines.',
        '- **load before**: the 1-minute load average when the run began (a quiet 2-core '
        'machine reads well under 1).',
        '- **start**: from spawning the nodes to every machine\'s first batch at the '
        'subscriber (all start at once and compete for the cores; a stagger, in the label, '
        'spreads the rotors\' run-ups, not the starts).',
        '',
        DATA_MARK + json.dumps(data, sort_keys=True) + ' -->',
    ]
    return '\n'.join(lines) + '\n'


def merge_ceiling(old, new):
    """A ceiling search split over runs (``--start-n``): the tries of both, the newer run's
    for an N tried twice; the ceiling is the largest N below the first that did not hold."""
    if not old:
        return new
    tried = {t['n']: t for t in old['tried']}
    tried.update({t['n']: t for t in new['tried']})
    ordered = [tried[n] for n in sorted(tried)]
    ceiling = None
    for t in ordered:
        if not t['holds']:
            break
        ceiling = t['n']
    commands = list(dict.fromkeys(old['command'].split('; ') + [new['command']]))
    return {'ceiling': ceiling, 'tried': ordered, 'command': '; '.join(commands),
            'date': new['date']}


# ---------------------------------------------------------------------------------------
def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument('--scene', help='N copies of this scene (with --n)')
    what.add_argument('--plant', help='a plant file (name under config/plants, or a path)')
    what.add_argument('--ceiling', metavar='SCENE',
                      help='the largest N copies of SCENE that hold (N = 1, 2, 3, 5, 8, 10, '
                           '13, ...)')
    parser.add_argument('--n', type=int, default=1, help='copies of --scene')
    parser.add_argument('--seconds', type=float, default=20.0,
                        help='measured span from every machine\'s first batch (s)')
    parser.add_argument('--start-timeout', type=float, default=150.0,
                        help='longest wait for every machine\'s first batch (s)')
    parser.add_argument('--max-n', type=int, default=16, help='largest N of --ceiling')
    parser.add_argument('--start-n', type=int, default=1,
                        help='first N of --ceiling (smaller ones taken as holding)')
    parser.add_argument('--ns', help='the N of --ceiling to try, comma-separated (e.g. 6,7 '
                                     'between a 5 that held and an 8 that did not)')
    parser.add_argument('--domain', type=int, help='DDS domain (default: a free one of '
                                                   '101..230)')
    parser.add_argument('--page', nargs='?', const=PAGE, metavar='FILE',
                        help=f'add the results to this page (default {PAGE})')
    parser.add_argument('--keep-logs', metavar='DIR', help="keep the processes' output here")
    parser.add_argument('--stagger', type=float, metavar='S',
                        help="machine i's rotor runs up i x S s after machine 0's (default: "
                             "the plant file's stagger; 0 for --scene; --ceiling: all at "
                             'once)')
    parser.add_argument('--hosts', type=int, default=0, metavar='K',
                        help='run the machines in K plant_host processes (--share 0/K ... '
                             'K-1/K of one plant file), not one vibration_node each')
    parser.add_argument('--stepping', choices=('shared', 'own'), default='shared',
                        help="with --hosts: plant_host's --stepping (default shared)")
    parser.add_argument('--json', metavar='FILE', help='write every figure of the runs here '
                        '(with the start-up: CPU per 1 s from the spawn)')
    args = parser.parse_args(argv)
    given = list(sys.argv[1:] if argv is None else argv)
    for flag in ('--domain', '--keep-logs', '--json'):   # not what was measured
        while flag in given:
            k = given.index(flag)
            del given[k:k + 2]
    given = [a for a in given if not a.startswith(('--domain=', '--keep-logs=', '--json='))]
    command = shlex.join(['bench/plant.py', *given])
    # a SIGTERM unwinds like Ctrl-C: the nodes and the reader are stopped, not left running
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    domain = args.domain or pick_domain(101 + os.getpid() % 130)
    date = datetime.date.today().isoformat()
    print(f'load before: {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores); '
          f'domain {domain}; {args.seconds:g} s from every machine\'s first batch', flush=True)

    form = '' if not args.hosts else (   # a row of its own on the page
        f' [{args.hosts} plant_host' + (', a thread per machine]' if args.stepping == 'own'
                                         else ']'))

    def run(label, machines, plant=None, stagger=None):
        load_before = os.getloadavg()[0]
        with tempfile.TemporaryDirectory(prefix='plant_bench_') as tmp:
            log_dir = tmp
            if args.keep_logs:
                log_dir = os.path.join(args.keep_logs, label)
                os.makedirs(log_dir, exist_ok=True)
            try:
                res = run_plant(label, machines, args, domain, log_dir, plant, stagger)
            except Exception as exc:   # one failed run still reports
                res = {'label': label, 'n': len(machines), 'status': 'error',
                       'scenes': sorted({s for _, s, _ in machines}),
                       'reason': f'bench: {type(exc).__name__}: {exc}'}
        res.update(command=command, date=date, load_before=load_before)
        print_run(res)
        return res

    runs, ceilings = {}, {}
    if args.plant:
        machines, name, stagger = plant_machines(args.plant, args.stagger)
        label = f'plant {name}' + (f' (stagger {stagger:g} s)' if stagger else '') + form
        runs[label] = run(label, machines, args.plant, args.stagger)
    elif args.scene:
        stagger = args.stagger or 0.0
        label = (f'{args.n} x {args.scene}' + (f' (stagger {stagger:g} s)' if stagger else '')
                 + form)
        runs[label] = run(label, scene_machines(args.scene, args.n, stagger), stagger=stagger)
    else:
        ns = list(CEILING_NS)
        while ns[-1] < args.max_n:
            ns.append(ns[-1] + 3)
        tried, ceiling = [], None
        if args.ns:
            ns = sorted(int(n) for n in args.ns.split(','))
        for n in [n for n in ns if args.start_n <= n <= args.max_n]:
            res = run(f'{n} x {args.ceiling}{form}', scene_machines(args.ceiling, n))
            tried.append({'n': n, 'worst': res.get('worst'), 'holds': res.get('holds', False)})
            if not res.get('holds'):
                break
            ceiling = n
        ceilings[args.ceiling + form] = {'ceiling': ceiling, 'tried': tried, 'command': command,
                                  'date': date}
        print(f'ceiling of {args.ceiling}: {ceiling if ceiling else "none"} (tried '
              + ', '.join(f'{t["n"]}: {_f(t["worst"], ".3f")}' for t in tried) + ')')
    if args.json:
        with open(args.json, 'w') as f:
            json.dump({'runs': _jsonable(runs), 'ceilings': _jsonable(ceilings)}, f, indent=1)
    if args.page:
        data = _load_page_data(args.page)
        data['machine'] = machine()
        data['runs'].update(_jsonable(runs))
        for scene, c in _jsonable(ceilings).items():
            data['ceilings'][scene] = merge_ceiling(data['ceilings'].get(scene), c)
        os.makedirs(os.path.dirname(os.path.abspath(args.page)), exist_ok=True)
        with open(args.page, 'w') as f:
            f.write(page(data))
        print(f'{args.page}: written')
    ok = all(r.get('holds') for r in runs.values())
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
