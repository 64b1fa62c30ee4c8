"""What one vibration_node costs: its CPU (% of one core) and where that time goes.

The node is started as users start it (``.venv/bin/vibration_node --ros-args --params-file
config/vibration_node.yaml -p scene:=NAME``, default scene hpotp: 2 kHz, its Imu stream at
1 kHz) in a DDS domain of its own, with the readers bench/node_scenes.py attaches (its own
scripts, ``node_scenes_readers.py``): a raw reader on every topic the node publishes (every
batch topic among them) and a stock Python reader per ``sensor_msgs/Imu`` topic; the monitor
too with ``--monitor``. Each run lasts ``--seconds`` from the first sample, the first
``--skip`` seconds of which are not counted.

What is measured:

* **CPU** of the node's process (utime + stime of all its threads, ``/proc/<pid>/stat``)
  over 1 s windows: median, peak and mean per run (``--runs`` runs, the node started afresh
  each time), and the median of the runs' medians;
* **by thread** (``/proc/<pid>/task/*/stat`` at the window's start and end): the stepping
  thread, the main thread (rclpy's executor: diagnostics, timers, commands), the middleware's
  threads (Fast DDS names them ``dds.*``) and the rest;
* **by stage** (``--breakdown``, on by default: one more run): the node is started through
  this script (``--child``), which wraps the functions each stage consists of (the table
  :data:`STAGES`) with counters of the stepping thread's CPU (``time.thread_time``), nested
  calls charged to the innermost stage, and writes them once a second; nothing of it is in
  the package, so a node started as users start it pays nothing for it. The stages: the
  Numba kernel, the Python around it, the forcing sampled for it, the sensor chain
  (channels, filters, tachometer), packing the messages, subscriber-count queries,
  publishing (the outbox and ``Publisher.publish``: rclpy and the middleware in the calling
  thread), waiting (the sleeps' system calls and wake-ups) and the wake-up loop itself. The
  wrappers cost about a microsecond a call: that run's total is a little above the plain
  runs'.

``--floor`` runs, instead of the node, its **publishing floor**: the same node (topics, QoS,
outbox, pacing, wake-ups, subscriber counts, ``Publisher.publish``, diagnostics) whose
physics, sensor chain and packing are replaced, once it is running, by replaying the items
200 of its chunks queued (the same bytes, re-timed: :func:`floor_child`; give ``--skip
8``). Its CPU is what putting this message stream on the wire costs in rclpy and the
middleware, whatever the physics costs: the floor under the node's own figure.
``--with-floor`` runs the floor in turns with the node's plain runs and prints and pages it
beside them.

``--tree DIR`` runs the node from another checkout of the package (``PYTHONPATH=DIR``, its
``config/``); ``--vs DIR`` runs that checkout's node and this one's in turns, run by run (the
before column of a change, from ``git archive`` of the commit before it, measured alike
however the machine's load drifts). ``--json FILE`` keeps the results; ``--before FILE`` (a
``--json`` of an earlier run) adds a before column to the printout and the page; ``--page FILE``
writes docs/bench/node-cost.md (date and machine once in its header, the command, the
tables). Quote figures taken on a quiet machine (nothing else running): the header gives the
load and the hypervisor's steal.

Usage::

    .venv/bin/python bench/node_cost.py [--scene hpotp] [--seconds 20] [--runs 3]
        [--skip 2] [--no-breakdown] [--monitor] [--node-arg ARG ...] [--domain N]
        [--tree DIR] [--vs DIR] [--json FILE] [--before FILE] [--page FILE]
    .venv/bin/python bench/node_cost.py --with-floor --skip 8 ...   # the floor in turns
    .venv/bin/python bench/node_cost.py --floor --no-breakdown --skip 8 [--runs 3] [--json FILE]
    .venv/bin/python bench/node_cost.py --render RESULTS.json --page FILE
"""
from __future__ import annotations

import argparse
import datetime
import importlib
import json
import os
import queue
import shlex
import signal
import statistics
import sys
import tempfile
import threading
import time

# Run as a script, never as a package: its neighbours are found either way.
if os.path.dirname(os.path.abspath(__file__)) not in sys.path:
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: Stage of each wrapped function: (module, attribute path, stage). A path the package does
#: not have (an older checkout) is skipped and listed. Nested calls count for the innermost.
STAGES = (
    ('impact_damper_sim.integrate.kernels.event_loop', 'advance', 'kernel'),
    ('impact_damper_sim.integrate.forcing', 'Forcing.sample', 'forcing'),
    ('impact_damper_sim.integrate.exact', 'ExactPropagator.advance', 'engine glue'),
    ('impact_damper_sim.integrate.simulation', 'Simulation.advance', 'engine glue'),
    ('impact_damper_sim.live.realtime', 'LiveSimulation.step', 'sensor chain'),
    ('impact_damper_sim.live.channel', 'SensorChannel.process', 'sensor chain'),
    ('impact_damper_sim.live.channel', 'SensorChannel.process_decimated', 'sensor chain'),
    ('impact_damper_sim.live.filters', 'StreamingDecimator.apply', 'sensor chain'),
    ('impact_damper_sim.recording.node_messages', 'NodeMessages.batch_items', 'packing'),
    ('impact_damper_sim.recording.node_messages', 'NodeMessages.time_items', 'packing'),
    ('impact_damper_sim.recording.node_messages', 'NodeMessages.state_message', 'packing'),
    ('impact_damper_sim.ros.node_publishing', 'Publishers.queue_batch', 'packing'),
    ('impact_damper_sim.ros.node_publishing', 'Publishers.queue_time', 'packing'),
    ('impact_damper_sim.ros.outlets', 'Outlet.has_subscribers', 'subscriber counts'),
    ('impact_damper_sim.live.pacing', 'Outbox.send_due', 'publishing'),
    ('impact_damper_sim.ros.outlets', 'Outlet.publish_raw', 'publishing'),
    ('rclpy.publisher', 'Publisher.publish', 'publish (rclpy, DDS)'),
    ('impact_damper_sim.ros.outlets', 'write_raw', 'publish (rclpy, DDS)'),
    ('time', 'sleep', 'waiting'),
    ('threading', 'Event.wait', 'waiting'),
    ('impact_damper_sim.ros.vibration_node', 'VibrationNode._run', 'wake-up loop'),
)
#: the stages in the order printed, with what each is
STAGE_ROWS = (
    ('kernel', 'the Numba kernel (event_loop.advance)'),
    ('engine glue', 'the Python around it (ExactPropagator/Simulation.advance)'),
    ('forcing', 'the forcing sampled for the kernel'),
    ('sensor chain', 'channels, filters, faults, tachometer (LiveSimulation.step)'),
    ('packing', 'messages packed and queued (batch_items, queue_batch, time_items)'),
    ('subscriber counts', 'Outlet.has_subscribers (get_subscription_count)'),
    ('publishing', 'the outbox and the outlets in Python (send_due, publish_raw)'),
    ('publish (rclpy, DDS)', 'Publisher.publish or outlets.write_raw: rclpy and the '
                             'middleware, this thread'),
    ('waiting', 'sleeps and waits: their system calls and wake-ups'),
    ('wake-up loop', 'the stepping loop itself (_run, _cycle, pacing, locks)'),
)
CHILD_PERIOD = 1.0   # s between two snapshots of the stage counters


# -- the instrumented node (child mode) --------------------------------------------------------
class _Ledger:
    """Stage CPU counters of one thread (the stepping thread), innermost stage charged."""

    def __init__(self):
        self.ident = None
        self.native = None
        self.cpu = {}
        self.calls = {}
        self.stack = []
        self.mark = 0.0

    def wrap(self, fn, stage):
        ledger = self
        clock = time.thread_time
        get_ident = threading.get_ident

        def staged(*args, **kwargs):
            if get_ident() != ledger.ident:
                return fn(*args, **kwargs)
            now = clock()
            stack = ledger.stack
            if stack:
                top = stack[-1]
                ledger.cpu[top] = ledger.cpu.get(top, 0.0) + now - ledger.mark
            stack.append(stage)
            ledger.calls[stage] = ledger.calls.get(stage, 0) + 1
            ledger.mark = now
            try:
                return fn(*args, **kwargs)
            finally:
                now = clock()
                top = stack.pop()
                ledger.cpu[top] = ledger.cpu.get(top, 0.0) + now - ledger.mark
                ledger.mark = now
        staged.__wrapped__ = fn
        return staged


def _install(ledger):
    """Wrap every function of :data:`STAGES` the package has; the paths it lacks."""
    missing = []
    for module_name, path, stage in STAGES:
        try:
            owner = importlib.import_module(module_name)
            *parents, name = path.split('.')
            for part in parents:
                owner = getattr(owner, part)
            fn = owner.__dict__[name] if isinstance(owner, type) else getattr(owner, name)
        except (ImportError, AttributeError, KeyError):
            missing.append(f'{module_name}.{path}')
            continue
        wrapped = ledger.wrap(fn, stage)
        if path == 'VibrationNode._run':   # the stepping thread: the one counted
            def run(self, _fn=fn, _wrapped=wrapped):
                ledger.ident = threading.get_ident()
                ledger.native = threading.get_native_id()
                return _wrapped(self)
            wrapped = run
        setattr(owner, name, wrapped)
    return missing


def child(out, argv):
    """Run the node with the stage counters, writing a snapshot to ``out`` every second."""
    ledger = _Ledger()
    missing = _install(ledger)
    stop = threading.Event()

    def snapshots():
        with open(out, 'w') as fh:
            fh.write(json.dumps({'missing': missing}) + '\n')
            while not stop.wait(CHILD_PERIOD):
                fh.write(json.dumps({'t': time.monotonic(), 'tid': ledger.native,
                                     'cpu': dict(ledger.cpu),
                                     'calls': dict(ledger.calls)}) + '\n')
                fh.flush()
    writer = threading.Thread(target=snapshots, daemon=True)
    writer.start()
    from impact_damper_sim.ros.vibration_node import main
    try:
        return main(['vibration_node', *argv])
    finally:
        stop.set()
        writer.join(timeout=2.0)


#: the floor child steps its first FLOOR_START chunks for real, keeps what the next
#: FLOOR_CAPTURE queue, and replays those (10 ms chunks: hpotp's rotor runs up over sim
#: 1-4 s, so 5-7 s is its running stream; give ``--skip 8`` so no real chunk is counted)
FLOOR_START = 500
FLOOR_CAPTURE = 200


def floor_child(argv):
    """Run the node as :func:`child` does, without stage counters, as its publishing floor:
    its first :data:`FLOOR_START` + :data:`FLOOR_CAPTURE` chunks are stepped for real, and
    the items each of the last :data:`FLOOR_CAPTURE` queued are kept (time from the chunk's
    start, outlet, bytes); every later chunk queues one of them again in turn, re-timed to
    the chunk, asks each outlet for its subscribers once per chunk as the node does, and
    moves the simulated time on by the chunk's length without computing anything."""
    from impact_damper_sim.ros import vibration_node as vn
    real_step = vn.VibrationNode._step
    kept = {}

    def step(self, n):
        rec = kept.setdefault(id(self), {'chunks': [], 'next': 0, 'stepped': 0})
        if rec['stepped'] < FLOOR_START:
            rec['stepped'] += 1
            return real_step(self, n)
        if len(rec['chunks']) < FLOOR_CAPTURE:
            t0 = self.live.t
            k0 = len(self.outbox.pending)   # only this thread takes items out
            ok = real_step(self, n)
            base = int(round(t0 * 1e9))
            items = [(ns - base, key, payload)
                     for ns, key, payload, _ in list(self.outbox.pending)[k0:]]
            rec['chunks'].append((self.live.t - t0, items))
            return ok
        dt, items = rec['chunks'][rec['next'] % len(rec['chunks'])]
        rec['next'] += 1
        with self._lock:
            base, wires = int(round(self.live.t * 1e9)), {}
            for dns, key, payload in items:
                wire = wires.get(key)
                if wire is None:
                    wire = wires[key] = key.has_subscribers()
                self.outbox.put(base + dns, key, payload, wire)
            self.live.sim.integrator.t = self.live.t + dt
        return True

    vn.VibrationNode._step = step
    return vn.main(['vibration_node', *argv])


# -- per-thread CPU ---------------------------------------------------------------------------
def thread_cpu(pid):
    """{tid: (name, user s, system s)} of the process's threads now."""
    from node_scenes_procs import CpuSampler
    out = {}
    try:
        tids = os.listdir(f'/proc/{pid}/task')
    except OSError:
        return out
    for tid in tids:
        try:
            with open(f'/proc/{pid}/task/{tid}/stat') as fh:
                text = fh.read()
        except OSError:
            continue
        name = text[text.index('(') + 1:text.rindex(')')]
        fields = text.rsplit(')', 1)[1].split()
        out[int(tid)] = (name, int(fields[11]) / CpuSampler.TICK,
                         int(fields[12]) / CpuSampler.TICK)
    return out


def thread_groups(before, after, pid, stepping, seconds):
    """% of one core by thread group over ``seconds``: stepping, main, middleware, other."""
    groups = {}
    for tid, (name, user, system) in after.items():
        _, user0, system0 = before.get(tid, (name, 0.0, 0.0))
        group = ('stepping' if tid == stepping else 'main (executor)' if tid == pid
                 else 'middleware (dds.*)' if name.startswith('dds.') else 'other threads')
        u, s = groups.get(group, (0.0, 0.0))
        groups[group] = (u + 100.0 * (user - user0) / seconds,
                         s + 100.0 * (system - system0) / seconds)
    return groups


# -- one run ------------------------------------------------------------------------------------
def run_once(args, domain, log_dir, staged, tree=None, floor=False):
    """Start the readers and the node (from checkout ``tree``, default this one), measure,
    stop everything; a dict of figures."""
    from node_scenes import MONITOR_EXES, NODE_EXE, base_env
    from node_scenes_figures import IMU, NODE_NAME
    from node_scenes_procs import Child, CpuSampler, settled_script
    from node_scenes_readers import PY_READER, RAW_READER

    tree = os.path.abspath(tree) if tree else ROOT
    env = dict(base_env(), ROS_DOMAIN_ID=str(domain))
    if tree != ROOT:
        env['PYTHONPATH'] = tree + os.pathsep + env.get('PYTHONPATH', '')
    py = sys.executable
    params = os.path.join(tree, 'config', 'vibration_node.yaml')
    node_args = ['--ros-args', '--params-file', params, '-p', f'scene:={args.scene}',
                 *args.node_arg]
    res = {'staged': staged, 'domain': domain}
    children = []
    cpu = CpuSampler(1.0)
    stages_out = os.path.join(log_dir, 'stages.jsonl')
    try:
        raw = Child('raw_reader', [py, '-c', RAW_READER, NODE_NAME, '/',
                                   os.path.join(log_dir, 'raw'), str(domain), '1'],
                    env, log_dir)
        children.append(raw)
        readers, assigned = [], {}

        def new_reader():
            k = len(readers)
            c = Child(f'python_reader_{k}', [py, '-c', PY_READER, str(k),
                                             os.path.join(log_dir, f'py{k}'), str(domain)],
                      env, log_dir, stdin=True)
            readers.append(c)
            children.append(c)
            return c
        new_reader()
        if args.monitor:
            exe = settled_script(MONITOR_EXES)
            children.append(Child('monitor', [exe, '--ros-args'], env, log_dir, pipe=False))
        deadline = time.monotonic() + 60.0
        for c in readers:   # up before the node, as node_scenes.py has them
            try:
                while c.get(max(deadline - time.monotonic(), 0.01)) not in ('warm', None):
                    pass
            except queue.Empty:
                pass
        if floor or args.floor:
            argv = [py, os.path.abspath(__file__), '--floor-child', *node_args]
        elif staged:
            argv = [py, os.path.abspath(__file__), '--child', stages_out, *node_args]
        else:
            exe = settled_script([NODE_EXE])
            if exe is None:
                raise RuntimeError(f'{NODE_EXE} missing')
            argv = [exe, *node_args]
        node = Child('node', argv, env, log_dir, pipe=False)
        children.append(node)
        cpu.add(node.pid)
        cpu.add('all')
        t_first = t0 = t1 = None
        threads0 = threads1 = None
        hard = node.t_spawn + args.start_timeout + args.skip + args.seconds + 5.0
        while True:
            try:
                line = raw.get(0.05)
            except queue.Empty:
                line = ''
            if line:
                try:
                    ev = json.loads(line)
                except ValueError:
                    ev = {}
                if ev.get('event') == 'topics':
                    for name, type_name in ev['topics']:
                        if type_name == IMU and name not in assigned:
                            free = [c for c in readers if c not in assigned.values()]
                            c = free[0] if free else new_reader()
                            c.send(name)
                            assigned[name] = c
                elif ev.get('event') == 'first_sample' and t_first is None:
                    t_first = ev['t']
                    t0, t1 = t_first + args.skip, t_first + args.skip + args.seconds
            now = time.monotonic()
            if node.proc.poll() is not None:
                res['error'] = f'node exited with status {node.proc.returncode}: ' + ' | '.join(
                    node.stderr_lines()[-3:])
                return res
            if t_first is None and now > node.t_spawn + args.start_timeout:
                res['error'] = f'no sample within {args.start_timeout:g} s'
                return res
            if t0 is not None and threads0 is None and now >= t0:
                threads0, t0 = thread_cpu(node.pid), now
            if t1 is not None and now >= t1:
                threads1, t1 = thread_cpu(node.pid), now
                break
            if now > hard:
                res['error'] = 'timed out'
                return res
        res['start_s'] = t_first - node.t_spawn
        per, mean = cpu.windows(node.pid, t0, t1)
        res['windows'] = per
        res['median'] = statistics.median(per) if per else None
        res['peak'] = max(per) if per else None
        res['mean'] = mean
        machine_per, machine_mean = cpu.windows('all', t0, t1)
        res['machine_busy'] = machine_mean
        res['seconds'] = t1 - t0
        stepping = None
        if staged:
            snaps = _snapshots(stages_out)
            res['missing'] = snaps[0].get('missing', []) if snaps else []
            a, b = _window(snaps[1:], t0, t1)
            if a and b:
                span = b['t'] - a['t']
                stepping = b['tid']
                res['stages'] = {k: 100.0 * (b['cpu'].get(k, 0.0) - a['cpu'].get(k, 0.0)) / span
                                 for k in b['cpu']}
                res['calls'] = {k: (b['calls'].get(k, 0) - a['calls'].get(k, 0)) / span
                                for k in b['calls']}
        res['threads'] = thread_groups(threads0, threads1, node.pid, stepping, t1 - t0)
        return res
    finally:
        for c in children:
            c.signal()
        for c in children:
            c.wait(15.0)
        cpu.stop()


def _snapshots(path):
    try:
        with open(path) as fh:
            return [json.loads(line) for line in fh if line.strip()]
    except (OSError, ValueError):
        return []


def _window(snaps, t0, t1):
    """The snapshots nearest the window's start and end (the counters are cumulative)."""
    if not snaps:
        return None, None
    a = min(snaps, key=lambda s: abs(s['t'] - t0))
    b = min(snaps, key=lambda s: abs(s['t'] - t1))
    return (a, b) if b['t'] - a['t'] > 0.5 else (None, None)


# -- the figures ----------------------------------------------------------------------------------
def summary(runs):
    """Median over the plain runs of each run's median, peak and mean (% of one core)."""
    plain = [r for r in runs if not r.get('staged') and r.get('median') is not None]
    if not plain:
        return {}
    return {'runs': len(plain),
            'median': statistics.median(r['median'] for r in plain),
            'peak': max(r['peak'] for r in plain),
            'mean': statistics.median(r['mean'] for r in plain),
            'each': [(r['median'], r['peak']) for r in plain]}


def _breakdown(data):
    staged = [r for r in data['runs'] if r.get('staged') and 'stages' in r]
    return staged[0] if staged else None


def report_lines(data, before=None):
    """The printout (and the page's tables): CPU, threads, stages; a before column."""
    now, then = data.get('summary') or {}, (before or {}).get('summary') or {}
    head = '| | before | after |' if before else '| | this run |'
    rule = '|---|---|---|' if before else '|---|---|'

    def cells(key, fmt='.1f', a=now, b=then):
        def one(d):
            v = d.get(key)
            return '-' if v is None else f'{v:{fmt}}'
        return f'{one(b)} | {one(a)}' if before else one(a)
    lines = ['CPU of the node process, % of one core (1 s windows)', '', head, rule,
             f'| median (median of the runs) | {cells("median")} |',
             f'| peak window (all runs) | {cells("peak")} |',
             f'| mean (median of the runs) | {cells("mean")} |',
             f'| runs | {cells("runs", "d")} |']
    for label, d in (('before', then), ('after' if before else 'runs', now)):
        if d.get('each'):
            each = ', '.join(f'{m:.1f} (peak {p:.1f})' for m, p in d['each'])
            lines.append(f'\n{label}: run medians {each}')
    floor_runs = (data.get('floor') or {}).get('summary') or {}
    if floor_runs:
        each = ', '.join(f'{m:.1f}' for m, _ in floor_runs['each'])
        lines.append(f"\nthe publishing floor (`--floor`: the same node and messages, the "
                     f"physics, sensor chain and packing replaced by replaying 200 chunks' "
                     f"items; in turns with the runs above): median {floor_runs['median']:.1f}"
                     f" % of a core, peak {floor_runs['peak']:.1f} (run medians {each})")
    b_now, b_then = _breakdown(data), _breakdown(before) if before else None
    if not (b_now or b_then):
        return lines

    def row(label, value):
        cells = [value(b_then), value(b_now)] if before else [value(b_now)]
        return f"| {label} | {' | '.join(cells)} |"

    def thread(group):
        def value(r):
            u, s = ((r or {}).get('threads') or {}).get(group, (None, None))
            return '-' if u is None else f'{u + s:.1f} (sys {s:.1f})'
        return value

    def figure(table, key, fmt):
        def value(r):
            v = ((r or {}).get(table) or {}).get(key)
            return '-' if v is None else f'{v:{fmt}}'
        return value

    def unstaged(r):
        if not r or 'stages' not in r:
            return '-'
        u, s = (r.get('threads') or {}).get('stepping', (0.0, 0.0))
        return f"{u + s - sum(r['stages'].values()):.1f}"
    order = ('stepping', 'main (executor)', 'middleware (dds.*)', 'other threads')
    groups = sorted({*((b_now or {}).get('threads') or {}),
                     *((b_then or {}).get('threads') or {})}, key=order.index)
    lines += ['', 'Where it goes: % of one core in the instrumented run', '', head, rule]
    lines += [row(f'thread: {g}', thread(g)) for g in groups]
    lines += [row(f'stepping: {key} ({what})', figure('stages', key, '.1f'))
              for key, what in STAGE_ROWS]
    lines.append(row('stepping: not in a stage (thread CPU less the stages)', unstaged))
    # what no Python around them would leave: the engine, the middleware's sends, the sleeps
    floor = ('kernel', 'publish (rclpy, DDS)', 'waiting')

    def share(part):
        def value(r):
            stages = (r or {}).get('stages')
            if not stages:
                return '-'
            inside = sum(v for k, v in stages.items() if k in floor)
            return f'{inside if part else sum(stages.values()) - inside:.1f}'
        return value
    lines += [row('stepping: kernel + publish (DDS) + waiting', share(True)),
              row('stepping: the Python stages (the rest)', share(False))]
    lines += ['', 'Calls per second in the stepping thread (instrumented run)', '', head,
              rule]
    lines += [row(label, figure('calls', key, '.0f')) for key, label in (
        ('waiting', 'sleeps/waits (wake-ups)'), ('kernel', 'kernel calls (chunks)'),
        ('publish (rclpy, DDS)', 'messages put on the wire'),
        ('subscriber counts', 'subscriber-count queries'))]
    return lines


def page(data, before=None):
    """docs/bench/node-cost.md: header once, the command, the tables, what they mean."""
    lines = ['# vibration_node: the CPU of one node, and where it goes', '',
             '<!-- written by bench/node_cost.py --page; do not edit: run it again -->', '',
             f"- **Date**: {data['date']}",
             f"- **Machine**: {data['machine']}",
             f"- **Command**: `{data['command']}`",
             f"- **Scene**: {data['scene']} ({data['seconds']:g} s per run, the first "
             f"{data['skip']:g} s after the first sample not counted); readers: a raw reader "
             'on every topic, a Python reader per Imu topic'
             + (', the monitor' if data.get('monitor') else ''),
             f"- **Load** (1-min average): {data['load_before']:.2f} before, "
             f"{data['load_after']:.2f} after; hypervisor steal {data['steal']:.1f} %", '']
    if data.get('before'):
        lines += ['Before: the same runs of another checkout (`--vs`'
                  + (f": {before['tree_note']}" if before.get('tree_note') else '')
                  + '), taking turns with these run by run.', '']
    elif before:
        lines += [f"Before: `{before['command']}` on {before['date']}"
                  + (f" ({before['tree_note']})" if before.get('tree_note') else ''), '']
    lines += report_lines(data, before)
    lines += ['', 'The CPU is utime + stime of all the node\'s threads from `/proc`; the '
              'thread rows are the same over the instrumented run\'s window (the middleware '
              'names its threads `dds.*`), and the stepping thread\'s stages are its own CPU '
              '(`time.thread_time`) in the functions of each stage, nested calls counted for '
              'the innermost. The wrappers cost about a microsecond a call (some 6,000 calls '
              'a second): the instrumented run reads a few points above the plain ones, whose '
              'figures the first table gives. The last two stage rows split the stepping '
              'thread into what no Python around them would leave (the Numba kernel, the '
              'middleware\'s sends to the readers, the sleeps) and the Python stages. How each '
              'figure is taken: `bench/node_cost.py`\'s docstring.', '']
    return '\n'.join(lines)


def _steal(before, after):
    from node_scenes_procs import _steal_percent
    return _steal_percent(before, after)


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ['--child']:
        return child(argv[1], argv[2:])
    if argv[:1] == ['--floor-child']:
        return floor_child(argv[1:])
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--scene', default='hpotp')
    parser.add_argument('--seconds', type=float, default=20.0,
                        help='measured span of each run (s)')
    parser.add_argument('--skip', type=float, default=2.0,
                        help='not counted after the first sample (s)')
    parser.add_argument('--runs', type=int, default=3, help='plain runs (the CPU figures)')
    parser.add_argument('--no-breakdown', action='store_true',
                        help='no instrumented run (no stages)')
    parser.add_argument('--monitor', action='store_true', help='the monitor reads too')
    parser.add_argument('--floor', action='store_true',
                        help="the node's publishing floor instead of the node (see above)")
    parser.add_argument('--with-floor', action='store_true',
                        help='the floor too, in turns with the node (printed and paged '
                             'beside it; give --skip 8)')
    parser.add_argument('--node-arg', action='append', default=[],
                        help='extra --ros-args argument for the node (repeat)')
    parser.add_argument('--domain', type=int, help='ROS_DOMAIN_ID (default: a free one)')
    parser.add_argument('--start-timeout', type=float, default=300.0)
    parser.add_argument('--tree', help='run the package from this checkout (PYTHONPATH)')
    parser.add_argument('--tree-note', default='', help='what --tree is, for the page')
    parser.add_argument('--json', help='write the results here')
    parser.add_argument('--before', help='a --json of the before run: printed beside')
    parser.add_argument('--vs', metavar='DIR',
                        help='the before checkout: its runs and this one\'s take turns')
    parser.add_argument('--vs-note', default='', help='what --vs is, for the page')
    parser.add_argument('--page', help='write the markdown page here')
    parser.add_argument('--render', metavar='JSON',
                        help='no run: print and write --page from a --json file')
    args = parser.parse_args(argv)
    if args.floor and (args.vs or args.page or not args.no_breakdown):
        parser.error('--floor: give --no-breakdown, and no --vs or --page (the floor is '
                     'quoted beside the node, not paged as it)')
    if args.render:
        with open(args.render) as fh:
            data = json.load(fh)
        print('\n'.join(report_lines(data, data.get('before'))))
        if args.page:
            with open(args.page, 'w') as fh:
                fh.write(page(data, data.get('before')))
        return 0
    from node_scenes_figures import machine
    from node_scenes_procs import _cpu_ticks, pick_domain
    domain = args.domain if args.domain is not None else pick_domain(101 + os.getpid() % 130)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    load_before, steal0 = os.getloadavg()[0], _cpu_ticks()
    # (checkout, staged): with --vs the two checkouts take turns, run by run, so that a
    # drift of the machine's speed during the call moves both columns alike
    trees = [args.vs, args.tree] if args.vs else [args.tree]
    plan = [(tree, False) for _ in range(args.runs)
            for tree in trees + (['floor'] if args.with_floor else [])]
    plan += [] if args.no_breakdown else [(tree, True) for tree in trees]
    runs = {tree: [] for tree in trees + ['floor']}
    for tree, staged in plan:
        with tempfile.TemporaryDirectory(prefix='node_cost_') as tmp:
            try:
                r = (run_once(args, domain, tmp, False, None, floor=True) if tree == 'floor'
                     else run_once(args, domain, tmp, staged, tree))
            except Exception as exc:   # a bench bug must not lose the other runs
                r = {'staged': staged, 'error': f'{type(exc).__name__}: {exc}'}
        runs[tree].append(r)
        what = ('floor, ' if tree == 'floor' else 'before, ' if args.vs and tree == args.vs
                else 'after, ' if args.vs else '') + (
            'instrumented' if staged else f'run {len(runs[tree])}')
        if 'error' in r:
            print(f'{what}: {r["error"]}', flush=True)
        else:
            print(f"{what}: node CPU median {r['median']:.1f} %, peak {r['peak']:.1f} %, "
                  f"mean {r['mean']:.1f} % of a core over {r['seconds']:.0f} s "
                  f"(machine busy {r['machine_busy']:.0f} %)", flush=True)
            if r.get('missing'):
                print(f"  not in this package (not staged): {', '.join(r['missing'])}")
    data = {'date': datetime.date.today().isoformat(), 'machine': machine(),
            'command': shlex.join(['bench/node_cost.py', *argv]), 'scene': args.scene,
            'seconds': args.seconds, 'skip': args.skip, 'monitor': args.monitor,
            'tree_note': args.tree_note, 'load_before': load_before,
            'load_after': os.getloadavg()[0], 'steal': _steal(steal0, _cpu_ticks()),
            'runs': runs[args.tree]}
    data['summary'] = summary(data['runs'])
    if args.with_floor:
        data['floor'] = {'runs': runs['floor'], 'summary': summary(runs['floor'])}
    before = None
    if args.vs:
        before = dict(data, runs=runs[args.vs], tree_note=args.vs_note,
                      command=data['command'])
        before['summary'] = summary(before['runs'])
        data['before'] = before
    elif args.before:
        with open(args.before) as fh:
            before = json.load(fh)
    print()
    print('\n'.join(report_lines(data, before)))
    if args.json:
        with open(args.json, 'w') as fh:
            json.dump(data, fh, indent=1)
    if args.page:
        with open(args.page, 'w') as fh:
            fh.write(page(data, before))
    return 0 if data['summary'] else 1


if __name__ == '__main__':
    sys.exit(main())
