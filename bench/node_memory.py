"""Where a vibration_node's memory goes, and what several machines cost in one process or many.

Three measurements (issue 39 items 2 and 3), each in processes of its own so that none sees
another's imports:

* **Breakdown** (always): a fresh interpreter imports what the node imports, stage by stage
  (NumPy, PyYAML, rclpy and the message packages, SciPy, Numba, our node's modules, the
  model's modules), builds the scene (FE model and modal reduction), the simulation (the
  compiled kernels loaded from Numba's cache), steps it, then builds the ROS node (rclpy, the
  DDS participant, the node's own model) and two more machines in the same process. After
  each stage: the resident set (``VmRSS``), its anonymous part (``RssAnon``: heap, Python
  objects, arrays, JIT code) and its file-backed part (``RssFile``: shared libraries, shared
  between processes), and the change. A second interpreter attributes the RSS growth during
  each module's import to its top-level package (exclusive of the packages it imports).
* **Running node**: the ``vibration_node`` console script on ``--scene`` for ``--seconds``
  (default 20; ``--seconds 900`` for a soak), ``VmRSS``, ``Pss`` and ``USS`` (its private
  pages: what it costs beside others that map the same libraries) every ``--every`` s.
* **Plant** (``--plant 1,3,5``): N machines of ``--scene`` in namespaces ``m0 .. m{N-1}``, as
  N ``vibration_node`` processes, as one ``plant_host`` process (``--executor single``
  and/or ``multi``) and, with ``--hosts K``, as K ``plant_host`` processes sharing them
  (``hostK-single``: machine i in process i mod K); each ``plant_host`` with one stepping
  thread for its machines, or with ``--stepping own`` one per machine (forms ``...-own``). A
  raw reader is subscribed to every batch topic (PointCloud2) of every machine and to
  ``/diagnostics``, from a wait set of its own (as bench/node_scenes.py's raw reader). After
  every machine's first status and ``--warmup`` s, ``--plant-seconds`` s are measured: the
  worst and the median 1 s window of the machines' ``real_time_factor_achieved`` (their
  ``/diagnostics``), the node processes' CPU (% of one core, all machines together), and at
  the end their summed RSS, PSS and USS.

Usage::

    python bench/node_memory.py [--scene hpotp] [--seconds 20] [--json F] [--page [PATH]]
    python bench/node_memory.py --seconds 900 --no-breakdown          # a soak
    python bench/node_memory.py --plant 1,3,5 --executor single,multi --json F --page
    python bench/node_memory.py --plant 6 --hosts 2 --no-processes --json F

``--json F`` merges this run's sections into F (so that short runs, each under its own
``flock -x /tmp/bench.lock``, make one page); ``--page`` writes docs/bench/node-memory.md
from it. Linux only (``/proc``).
"""
from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import signal
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PAGE = os.path.join(ROOT, 'docs', 'bench', 'node-memory.md')
MB = 1024.0   # kB per MB (/proc reports kB)


# ------------------------------------------------------------------------------ /proc
def status_kb(pid='self'):
    """``VmRSS``, ``RssAnon``, ``RssFile`` of a process (dict of kB; empty when gone)."""
    out = {}
    try:
        with open(f'/proc/{pid}/status') as f:
            for line in f:
                key = line.split(':', 1)[0]
                if key in ('VmRSS', 'RssAnon', 'RssFile'):
                    out[key] = int(line.split()[1])
    except (OSError, ValueError):
        pass
    return out


def rollup_kb(pid):
    """``Rss``, ``Pss`` and ``USS`` (Private_Clean + Private_Dirty) of a process (kB)."""
    out = {'Rss': 0, 'Pss': 0, 'USS': 0}
    try:
        with open(f'/proc/{pid}/smaps_rollup') as f:
            for line in f:
                key, _, rest = line.partition(':')
                if key in ('Rss', 'Pss'):
                    out[key] = int(rest.split()[0])
                elif key in ('Private_Clean', 'Private_Dirty'):
                    out['USS'] += int(rest.split()[0])
    except (OSError, ValueError, IndexError):
        return {}
    return out


def cpu_seconds(pid):
    """utime + stime of a process (s), nan when gone."""
    try:
        with open(f'/proc/{pid}/stat') as f:
            fields = f.read().rsplit(')', 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')
    except (OSError, ValueError, IndexError):
        return math.nan


def machine_busy_seconds():
    """CPU seconds the whole machine has been busy (``/proc/stat``: all but idle and
    iowait), nan when unreadable."""
    try:
        with open('/proc/stat') as f:
            ticks = [int(x) for x in f.readline().split()[1:9]]
    except (OSError, ValueError):
        return math.nan
    return (sum(ticks) - ticks[3] - ticks[4]) / os.sysconf('SC_CLK_TCK')


def machine():
    """This machine in words: CPU model and core count."""
    model = ''
    try:
        with open('/proc/cpuinfo') as fh:
            model = next((line.split(':', 1)[1].strip() for line in fh
                          if line.startswith('model name')), '')
    except OSError:
        pass
    cores = os.cpu_count() or 0
    return f'{model or platform.machine()}, {cores} core{"s" if cores != 1 else ""}'


def env_for(domain):
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED='1')
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    env.setdefault('AMENT_PREFIX_PATH', sys.prefix)
    return env


def script(name):
    """A console script of this Python's environment (``<prefix>/bin/<name>``)."""
    path = os.path.join(sys.prefix, 'bin', name)
    if not os.path.exists(path):
        raise SystemExit(f'node_memory: {path} not found: run make (the editable install)')
    return path


# ------------------------------------------------------------------------- breakdown child
#: (stage, modules it imports) before the model is built
IMPORT_STAGES = (
    ('NumPy', ('numpy',)),
    ('PyYAML', ('yaml',)),
    ('rclpy and the message packages', (
        'rclpy', 'rclpy.node', 'rclpy.executors', 'std_msgs.msg', 'sensor_msgs.msg',
        'geometry_msgs.msg', 'diagnostic_msgs.msg', 'std_srvs.srv', 'rcl_interfaces.msg',
        'rosgraph_msgs.msg')),
    ('SciPy (linalg, sparse, sparse.linalg)', (
        'scipy.linalg', 'scipy.sparse', 'scipy.sparse.linalg')),
    ('Numba and llvmlite', ('numba', 'llvmlite.binding')),
    ("the node's modules (ros, live, recording)", ('impact_damper_sim.ros.vibration_node',)),
    ("the model's modules (scene, fem, modal, integrate, kernels)", (
        'impact_damper_sim.scene.build', 'impact_damper_sim.scene.catalog',
        'impact_damper_sim.integrate.exact', 'impact_damper_sim.integrate.newmark',
        'impact_damper_sim.integrate.kernels.prefetch', 'impact_damper_sim.modal',
        'impact_damper_sim.fem')),
)
#: modules the node must never import (offline, plotting, studies): reported when present
NEVER = ('matplotlib', 'scipy.signal', 'scipy.optimize', 'scipy.stats', 'scipy.interpolate',
         'impact_damper_sim.studies', 'impact_damper_sim.cli', 'mcap', 'dask')


def child_stages(scene, domain):
    """Print one JSON line per stage: name, VmRSS, RssAnon, RssFile (kB), seconds."""
    import gc
    import importlib

    def emit(name, t0, **extra):
        print(json.dumps(dict(stage=name, s=time.perf_counter() - t0, **status_kb(),
                              **extra)), flush=True)

    emit('Python interpreter', time.perf_counter())
    for name, modules in IMPORT_STAGES:
        t0 = time.perf_counter()
        for m in modules:
            importlib.import_module(m)
        emit(name, t0)
    import rclpy
    from rclpy.parameter import Parameter

    from impact_damper_sim.live.realtime import LiveSimulation
    from impact_damper_sim.live.streams import live_scene
    from impact_damper_sim.ros.vibration_node import VibrationNode
    t0 = time.perf_counter()
    model, target = live_scene(scene)
    emit('scene built (FE model, modal reduction)', t0)
    t0 = time.perf_counter()
    live = LiveSimulation(model, initial_target=target)
    emit('simulation built (compiled kernels loaded from the cache)', t0)
    t0 = time.perf_counter()
    live.step(0)
    live.step(int(live.sample_rate))
    emit('first step and 1 s stepped', t0)
    t0 = time.perf_counter()
    rclpy.init(domain_id=domain)
    emit('rclpy.init (DDS participant)', t0)
    nodes = []
    for k in range(3):
        t0 = time.perf_counter()
        nodes.append(VibrationNode(f'memory_{k}', start_stepping=False,
                                   parameter_overrides=[Parameter('scene', value=scene)]))
        nodes[-1].tick()
        emit('the ROS node (its own model, topics, services)' if k == 0 else
             f'machine {k + 1} in the same process', t0)
    t0 = time.perf_counter()
    del model, live
    gc.collect()
    emit('the stand-alone model of the first stages dropped', t0,
         never=[m for m in NEVER if m in sys.modules],
         coverage='coverage' in sys.modules)
    for node in nodes:
        node.destroy_node()
    rclpy.try_shutdown()


def child_packages(scene, domain):
    """Print JSON: RSS growth (kB) during each module's import, exclusive of the imports it
    makes, summed per top-level package (``impact_damper_sim`` per subpackage), while the
    node's module is imported and one node is built; and the total growth."""
    import collections
    import importlib.abc

    own = collections.Counter()
    stack = []

    class Loader(importlib.abc.Loader):
        def __init__(self, inner):
            self.inner = inner

        def __getattr__(self, attr):   # resources, get_code, ...: the real loader's
            return getattr(self.inner, attr)

        def create_module(self, spec):
            return self.inner.create_module(spec)

        def exec_module(self, module):
            r0 = status_kb().get('VmRSS', 0)
            stack.append(0)
            try:
                self.inner.exec_module(module)
            finally:
                child = stack.pop()
                grown = status_kb().get('VmRSS', 0) - r0
                own[module.__name__] += grown - child
                if stack:
                    stack[-1] += grown

    class Finder(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path, target=None):
            for finder in sys.meta_path:
                if finder is self or not hasattr(finder, 'find_spec'):
                    continue
                spec = finder.find_spec(name, path, target)
                if spec is not None:
                    if spec.loader is not None and hasattr(spec.loader, 'exec_module'):
                        spec.loader = Loader(spec.loader)
                    return spec
            return None

    sys.meta_path.insert(0, Finder())
    r0 = status_kb()['VmRSS']
    import rclpy
    from rclpy.parameter import Parameter

    from impact_damper_sim.ros.vibration_node import VibrationNode
    rclpy.init(domain_id=domain)
    node = VibrationNode('memory', start_stepping=False,
                         parameter_overrides=[Parameter('scene', value=scene)])
    node.tick()
    total = status_kb()['VmRSS'] - r0
    packages = collections.Counter()
    for name, kb in own.items():
        parts = name.split('.')
        packages['.'.join(parts[:2]) if parts[0] == 'impact_damper_sim' else parts[0]] += kb
    print(json.dumps({'total': total, 'imports': sum(own.values()),
                      'packages': packages.most_common()}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


def run_child(kind, scene, domain):
    out = subprocess.run([sys.executable, os.path.abspath(__file__), '--child', kind, scene,
                          str(domain)], capture_output=True, text=True, env=env_for(domain),
                         cwd=ROOT, timeout=600)
    if out.returncode != 0:
        raise SystemExit(f'node_memory: the {kind} child failed:\n{out.stderr[-3000:]}')
    return [json.loads(line) for line in out.stdout.splitlines() if line.startswith('{')]


def breakdown(scene, domain):
    rows = run_child('stages', scene, domain)
    packages = run_child('packages', scene, domain)[0]
    return {'scene': scene, 'stages': rows, 'packages': packages}


def print_breakdown(b):
    print(f"\nbreakdown, scene {b['scene']} (MB; anon = heap, objects, arrays, JIT code; file "
          '= shared libraries)')
    print(f"{'stage':60s} {'RSS':>7s} {'delta':>7s} {'anon':>7s} {'file':>7s} {'s':>5s}")
    prev = None
    for r in b['stages']:
        rss = r['VmRSS'] / MB
        delta = '' if prev is None else f'{rss - prev:+7.1f}'
        print(f"{r['stage'][:60]:60s} {rss:7.1f} {delta:>7s} {r['RssAnon'] / MB:7.1f} "
              f"{r['RssFile'] / MB:7.1f} {r['s']:5.2f}")
        prev = rss
    last = b['stages'][-1]
    print(f"never-imports present: {last.get('never') or 'none'}; coverage imported (by "
          f"Numba, when installed): {last.get('coverage')}")
    p = b['packages']
    print(f"\nRSS grown while importing, by package (MB; imports {p['imports'] / MB:.1f} of "
          f"{p['total'] / MB:.1f} for one node):")
    for name, kb in p['packages'][:14]:
        print(f'  {kb / MB:6.1f}  {name}')


# ------------------------------------------------------------------------------ running
def wait_ready(proc, log_path, marker, timeout):
    """Wait until ``marker`` appears in the log (or the process ends); True when it did."""
    end = time.monotonic() + timeout
    while time.monotonic() < end and proc.poll() is None:
        with open(log_path, errors='replace') as f:
            if marker in f.read():
                return True
        time.sleep(0.2)
    return False


def running(scene, seconds, every, domain):
    """RSS of the vibration_node process from ready to ``seconds`` later."""
    log = tempfile.NamedTemporaryFile('w', suffix='.log', delete=False)
    proc = subprocess.Popen([script('vibration_node'), '--ros-args', '-p', f'scene:={scene}'],
                            env=env_for(domain), stdout=log, stderr=log, cwd=ROOT,
                            start_new_session=True)
    samples = []
    try:
        if not wait_ready(proc, log.name, 'integrator dt', 300):
            raise SystemExit(f'node_memory: vibration_node did not start; see {log.name}')
        t0 = time.monotonic()
        while True:
            t = time.monotonic() - t0
            samples.append(dict(t=t, **status_kb(proc.pid), **rollup_kb(proc.pid)))
            if t >= seconds or proc.poll() is not None:
                break
            time.sleep(min(every, max(0.0, seconds - t)))
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            rc = proc.wait(30)
        except subprocess.TimeoutExpired:
            proc.kill()
            rc = proc.wait()
    return {'scene': scene, 'seconds': seconds, 'samples': samples, 'exit': rc}


def print_running(r):
    s = r['samples']
    first, last = s[0], s[-1]
    peak = max(x['VmRSS'] for x in s)
    print(f"\nvibration_node on {r['scene']}: RSS {first['VmRSS'] / MB:.1f} MB when ready, "
          f"{last['VmRSS'] / MB:.1f} MB after {last['t']:.0f} s (peak {peak / MB:.1f}); "
          f"anon {last['RssAnon'] / MB:.1f}, file {last['RssFile'] / MB:.1f}, PSS "
          f"{last.get('Pss', 0) / MB:.1f}, USS {last.get('USS', 0) / MB:.1f} MB; exit "
          f"{r['exit']}")


# ------------------------------------------------------------------------- plant reader
def child_reader(namespaces, domain, out):
    """Raw reader of the machines' batch topics and /diagnostics (a wait set of its own);
    on SIGINT writes JSON to ``out``: per status name its (arrival, rtf, cpu) windows, per
    namespace its message count, and the time each machine's first status arrived."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rclpy.serialization import deserialize_message
    from rclpy.signals import SignalHandlerOptions
    from sensor_msgs.msg import PointCloud2

    stop = []
    rclpy.init(domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    node = rclpy.create_node('bench_memory_reader', start_parameter_services=False,
                             enable_rosout=False)
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    prefixes = tuple(f'/{ns}/' for ns in namespaces)
    subs, known = [], set()
    counts = {ns: 0 for ns in namespaces}
    windows, first = {}, {}

    def discover():
        for name, types in node.get_topic_names_and_types():
            if name in known:
                continue
            ns = next((p.strip('/') for p in prefixes if name.startswith(p)), None)
            if name == '/diagnostics':
                cls = DiagnosticArray
            elif ns is not None and 'sensor_msgs/msg/PointCloud2' in types:
                cls = PointCloud2
            else:
                continue
            known.add(name)
            subs.append((node.create_subscription(cls, name, lambda _: None, qos, raw=True),
                         cls, ns))

    t_next, wait_set, size = 0.0, None, 0
    print(json.dumps({'event': 'ready'}), flush=True)
    while not stop:
        now = time.monotonic()
        if now >= t_next:
            discover()
            t_next = now + 0.5
        if not subs:
            time.sleep(0.05)
            continue
        if len(subs) != size:
            wait_set = _rclpy.WaitSet(len(subs), 0, 0, 0, 0, 0, node.context.handle)
            size = len(subs)
        wait_set.clear_entities()
        for sub, _, _ in subs:
            wait_set.add_subscription(sub.handle)
        wait_set.wait(50_000_000)
        ready = wait_set.get_ready_entities('subscription')
        for sub, cls, ns in subs:
            if sub.handle.pointer not in ready:
                continue
            with sub.handle:
                for _ in range(1000):
                    got = sub.handle.take_message(sub.msg_type, True)
                    if got is None:
                        break
                    if cls is PointCloud2:
                        counts[ns] += 1
                        continue
                    t = time.monotonic()
                    for s in deserialize_message(got[0], DiagnosticArray).status:
                        if not s.name.endswith('vibration_node: simulation'):
                            continue
                        values = {kv.key: kv.value for kv in s.values}
                        first.setdefault(s.name, t)
                        windows.setdefault(s.name, []).append(
                            (t, float(values.get('real_time_factor_achieved', 'nan')),
                             float(values.get('cpu_percent', 'nan'))))
    with open(out, 'w') as f:
        json.dump({'windows': windows, 'counts': counts, 'first': first}, f)
    node.destroy_node()
    rclpy.try_shutdown()


def plant_run(n, scene, form, seconds, warmup, domain, stepping='shared'):
    """One plant of ``n`` machines as ``form`` ('processes', 'host-single', 'host-multi'):
    worst/median 1 s window, CPU, memory."""
    namespaces = [f'm{k}' for k in range(n)]
    env = env_for(domain)
    tmp = tempfile.mkdtemp(prefix='node_memory_')
    out = os.path.join(tmp, 'reader.json')
    procs = []
    reader = subprocess.Popen([sys.executable, os.path.abspath(__file__), '--child', 'reader',
                               ','.join(namespaces), str(domain), out], env=env, cwd=ROOT,
                              stdout=subprocess.PIPE, stderr=open(out + '.log', 'w'),
                              text=True, start_new_session=True)
    try:
        reader.stdout.readline()   # ready
        if form == 'processes':
            for k, ns in enumerate(namespaces):
                procs.append(subprocess.Popen(
                    [script('vibration_node'), '--ros-args', '-r', f'__ns:=/{ns}',
                     '-p', f'scene:={scene}', '-p', f'noise_seed:={k}',
                     '-p', f'publish_clock:={"true" if k == 0 else "false"}'],
                    env=env, cwd=ROOT, stdout=subprocess.DEVNULL,
                    stderr=open(os.path.join(tmp, f'{ns}.log'), 'w'),
                    start_new_session=True))
        else:   # 'host-E' one plant_host, 'hostK-E' K of them sharing the machines
            hosts = int(form.split('-')[0][4:] or 1)
            for h in range(hosts):
                share = namespaces[h::hosts]
                procs.append(subprocess.Popen(
                    [script('impact_damper_plant_host'), '--executor', form.split('-')[1],
                     '--stepping', stepping,
                     '--seed', str(100 * h), '--clock', 'first' if h == 0 else 'none',
                     '--machines', *(f'{ns}:{scene}' for ns in share)],
                    env=env, cwd=ROOT, stdout=subprocess.DEVNULL,
                    stderr=open(os.path.join(tmp, f'plant_host{h}.log'), 'w'),
                    start_new_session=True))
        # every machine's first status: read the processes' logs for the ready line
        end = time.monotonic() + 300
        logs = [os.path.join(tmp, f'{ns}.log') for ns in namespaces] \
            if form == 'processes' else [os.path.join(tmp, f'plant_host{h}.log')
                                         for h in range(len(procs))]
        marker = 'integrator dt' if form == 'processes' else 'machines in one process'
        while time.monotonic() < end:
            if all(p.poll() is None for p in procs) and all(
                    marker in open(path, errors='replace').read() for path in logs):
                break
            if any(p.poll() is not None for p in procs):
                raise SystemExit(f'node_memory: a node process ended; logs in {tmp}')
            time.sleep(0.2)
        time.sleep(warmup + 1.0)
        t0 = time.monotonic()
        cpu0 = sum(cpu_seconds(p.pid) for p in procs)
        reader0, busy0 = cpu_seconds(reader.pid), machine_busy_seconds()
        time.sleep(seconds)
        t1 = time.monotonic()
        cpu1 = sum(cpu_seconds(p.pid) for p in procs)
        reader1, busy1 = cpu_seconds(reader.pid), machine_busy_seconds()
        mem = [dict(**status_kb(p.pid), **rollup_kb(p.pid)) for p in procs]
    finally:
        for p in procs:
            p.send_signal(signal.SIGINT)
        exits = []
        for p in procs:
            try:
                exits.append(p.wait(30))
            except subprocess.TimeoutExpired:
                p.kill()
                exits.append(p.wait())
        reader.send_signal(signal.SIGINT)
        try:
            reader.wait(30)
        except subprocess.TimeoutExpired:
            reader.kill()
            reader.wait()
    with open(out) as f:
        got = json.load(f)
    rtf = []
    per_machine = {}
    for name, ws in got['windows'].items():
        inside = [w[1] for w in ws if t0 + 0.5 <= w[0] <= t1 + 0.5 and w[1] == w[1]]
        per_machine[name] = min(inside) if inside else math.nan
        rtf += inside
    rtf.sort()
    return {
        'n': n, 'scene': scene, 'seconds': t1 - t0,
        # a thread per machine in a plant_host: its own rows
        'form': form + ('-own' if stepping == 'own' and form != 'processes' else ''),
        'statuses': len(got['windows']), 'windows': len(rtf),
        'rtf_worst': rtf[0] if rtf else math.nan,
        'rtf_median': rtf[len(rtf) // 2] if rtf else math.nan,
        'per_machine_worst': per_machine,
        'cpu_percent': 100.0 * (cpu1 - cpu0) / (t1 - t0),
        'reader_cpu_percent': 100.0 * (reader1 - reader0) / (t1 - t0),
        # everything else on the machine (other processes, the bench, the kernel)
        'others_cpu_percent': 100.0 * ((busy1 - busy0) - (cpu1 - cpu0)
                                       - (reader1 - reader0)) / (t1 - t0),
        'rss_mb': sum(m.get('VmRSS', 0) for m in mem) / MB,
        'pss_mb': sum(m.get('Pss', 0) for m in mem) / MB,
        'uss_mb': sum(m.get('USS', 0) for m in mem) / MB,
        'batches': got['counts'], 'exits': exits,
    }


def print_plant(r):
    print(f"{r['form']:12s} N={r['n']} {r['scene']}: RTF worst {r['rtf_worst']:.3f} median "
          f"{r['rtf_median']:.3f} ({r['windows']} windows of {r['statuses']} machines); CPU "
          f"{r['cpu_percent']:.0f} % of a core (reader {r['reader_cpu_percent']:.0f}, others "
          f"{r['others_cpu_percent']:.0f}); RSS {r['rss_mb']:.0f} MB, PSS "
          f"{r['pss_mb']:.0f}, USS {r['uss_mb']:.0f}; exits {r['exits']}")


# ---------------------------------------------------------------------------------- page
def _mb(kb):
    return f'{kb / MB:.1f}'


def page(data):
    """The markdown page of the merged results."""
    lines = ['# vibration_node memory, and several machines in one process: measured', '',
             '<!-- written by bench/node_memory.py --page; do not edit: run it again -->', '',
             f"- **Date**: {data.get('date', 'not recorded')}",
             f"- **Machine**: {data.get('machine', 'not recorded')}",
             '- **Commands**: ' + '; '.join(f'`{c}`' for c in data.get('commands', [])), '',
             'How each figure is taken: `bench/node_memory.py`\'s docstring. RSS counts '
             'every resident page, shared libraries too; PSS shares each shared page among '
             'the processes that map it; USS is what a process holds alone (what one more '
             'such process adds).', '']
    b = data.get('breakdown')
    if b:
        lines += [f"## Where one node's memory goes (scene {b['scene']})", '',
                  '| stage | RSS MB | change | anon MB | file MB |', '|---|---|---|---|---|']
        prev = None
        for r in b['stages']:
            change = '' if prev is None else f"{(r['VmRSS'] - prev) / MB:+.1f}"
            lines.append(f"| {r['stage']} | {_mb(r['VmRSS'])} | {change} | "
                         f"{_mb(r['RssAnon'])} | {_mb(r['RssFile'])} |")
            prev = r['VmRSS']
        last = b['stages'][-1]
        p = b['packages']
        lines += ['', f"Modules the node must not import, present: "
                  f"{', '.join(last.get('never') or []) or 'none'}. Numba imports `coverage` "
                  'when it is installed (the test tools; '
                  f"{'imported here' if last.get('coverage') else 'not installed here'}).", '',
                  f"RSS grown while importing, by package (one node, scene {b['scene']}: "
                  f"{p['imports'] / MB:.0f} MB of its {p['total'] / MB:.0f} MB growth happens "
                  'inside imports; the rest is the kernels loaded and the model):', '',
                  '| package | MB |', '|---|---|']
        lines += [f'| {name} | {_mb(kb)} |' for name, kb in p['packages'][:14]]
    r = data.get('running')
    if r:
        s = r['samples']
        first, last = s[0], s[-1]
        lines += ['', f"## A running node (scene {r['scene']}, {last['t']:.0f} s)", '',
                  '| | RSS MB | anon MB | file MB | PSS MB | USS MB |',
                  '|---|---|---|---|---|---|']
        for label, x in (('ready', first), (f"after {last['t']:.0f} s", last)):
            lines.append(f"| {label} | {_mb(x['VmRSS'])} | {_mb(x['RssAnon'])} | "
                         f"{_mb(x['RssFile'])} | {_mb(x.get('Pss', 0))} | "
                         f"{_mb(x.get('USS', 0))} |")
        lines.append(f"\nPeak RSS over the run {max(x['VmRSS'] for x in s) / MB:.1f} MB.")
    plant = data.get('plant')
    if plant:
        rows = sorted(plant.values(), key=lambda x: (x['n'], x['form']))
        lines += ['', '## N machines: N processes or one process', '',
                  'Each run: N machines of the scene in namespaces m0.., a raw reader on '
                  'every batch topic and /diagnostics; the worst and the median 1 s window '
                  "of all machines' `real_time_factor_achieved`; CPU of the node processes "
                  'together (% of one core); memory at the end, summed over the node '
                  'processes (the reader\'s own CPU and everyone else\'s, from `/proc/stat`, '
                  'beside it: about +-10 points). Forms: `processes` N `vibration_node` '
                  'processes; `host-single` / `host-multi` one `plant_host` with a single- or '
                  'multi-threaded executor; `host2-single` two `plant_host` processes, machine '
                  'i in process i mod 2. A `plant_host` steps all its machines in one thread '
                  '(`--stepping shared`); a form ending in `-own` gave each machine a thread '
                  'of its own (`--stepping own`).', '',
                  '| N | scene | form | RTF worst | median | CPU % | reader % | others % | '
                  'RSS MB | PSS MB | USS MB |',
                  '|---|---|---|---|---|---|---|---|---|---|---|']
        for x in rows:
            lines.append(f"| {x['n']} | {x['scene']} | {x['form']} | {x['rtf_worst']:.3f} | "
                         f"{x['rtf_median']:.3f} | {x['cpu_percent']:.0f} | "
                         f"{x.get('reader_cpu_percent', math.nan):.0f} | "
                         f"{x.get('others_cpu_percent', math.nan):.0f} | "
                         f"{x['rss_mb']:.0f} | {x['pss_mb']:.0f} | {x['uss_mb']:.0f} |")
        host = {x['n']: x for x in rows if x['form'] == 'host-single'}
        ns = sorted(host)
        if len(ns) >= 2:
            a, z = host[ns[0]], host[ns[-1]]
            lines += ['', f"In one process each machine past the first adds "
                      f"{(z['rss_mb'] - a['rss_mb']) / (z['n'] - a['n']):.1f} MB RSS "
                      f"(N = {a['n']} to {z['n']}, {a['form']})."]
        procs = {x['n']: x for x in rows if x['form'] == 'processes'}
        if len(procs) >= 2:
            a, z = procs[min(procs)], procs[max(procs)]
            lines += ['', f"As processes each machine past the first adds "
                      f"{(z['rss_mb'] - a['rss_mb']) / (z['n'] - a['n']):.0f} MB RSS and "
                      f"{(z['uss_mb'] - a['uss_mb']) / (z['n'] - a['n']):.0f} MB USS "
                      f"(N = {a['n']} to {z['n']}): the libraries' file pages are shared, "
                      'their heaps, Python objects and JIT code are not.']
    return '\n'.join(lines) + '\n'


# ---------------------------------------------------------------------------------- main
def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ['--child']:
        kind, rest = argv[1], argv[2:]
        if kind == 'stages':
            return child_stages(rest[0], int(rest[1]))
        if kind == 'packages':
            return child_packages(rest[0], int(rest[1]))
        if kind == 'reader':
            return child_reader(rest[0].split(','), int(rest[1]), rest[2])
        raise SystemExit(f'unknown child {kind}')
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--scene', default='hpotp')
    parser.add_argument('--seconds', type=float, default=20.0,
                        help='run the node this long (s); 900 for a soak; 0 = not at all')
    parser.add_argument('--every', type=float, default=None,
                        help='RSS sample period of the running node (s; default seconds/20)')
    parser.add_argument('--no-breakdown', action='store_true')
    parser.add_argument('--plant', default='', help='machine counts, e.g. 1,3,5')
    parser.add_argument('--executor', default='single',
                        help="plant_host executors to run: single, multi, 'single,multi' or none")
    parser.add_argument('--stepping', choices=('shared', 'own'), default='shared',
                        help="plant_host's --stepping (default shared: one thread for all "
                             'machines)')
    parser.add_argument('--no-processes', action='store_true',
                        help='plant: only plant_host, not N processes')
    parser.add_argument('--hosts', type=int, default=1,
                        help='plant: also split the machines over this many plant_host '
                             'processes (e.g. 2: one per core)')
    parser.add_argument('--plant-seconds', type=float, default=30.0)
    parser.add_argument('--warmup', type=float, default=3.0)
    parser.add_argument('--domain', type=int, default=68)
    parser.add_argument('--json', default=None, help='merge the results into this file')
    parser.add_argument('--page', nargs='?', const=PAGE, default=None)
    args = parser.parse_args(argv)
    data = {}
    if args.json and os.path.exists(args.json):
        with open(args.json) as f:
            data = json.load(f)
    data['date'] = datetime.date.today().isoformat()
    data['machine'] = machine()
    command = 'bench/node_memory.py ' + ' '.join(a for a in argv if a != args.json
                                                 and a != '--json')
    data.setdefault('commands', [])
    if args.plant or not args.no_breakdown or args.seconds > 0:
        data['commands'] = [c for c in data['commands'] if c != command] + [command]
    if not args.plant:
        if not args.no_breakdown:
            data['breakdown'] = breakdown(args.scene, args.domain)
            print_breakdown(data['breakdown'])
        if args.seconds > 0:
            every = args.every or max(1.0, args.seconds / 20)
            data['running'] = running(args.scene, args.seconds, every, args.domain)
            print_running(data['running'])
    else:
        forms = ([] if args.no_processes else ['processes']) + \
            [f'host-{e}' for e in args.executor.split(',') if e in ('single', 'multi')] + \
            ([f'host{args.hosts}-single'] if args.hosts > 1 else [])
        data.setdefault('plant', {})
        for n in (int(x) for x in args.plant.split(',')):
            for form in forms:
                r = plant_run(n, args.scene, form, args.plant_seconds, args.warmup,
                              args.domain, stepping=args.stepping)
                data['plant'][f"{r['scene']} {n} {r['form']}"] = r
                print_plant(r)
    if args.json:
        with open(args.json, 'w') as f:
            json.dump(data, f, indent=1)
    if args.page:
        with open(args.page, 'w') as f:
            f.write(page(data))
        print(f'wrote {args.page}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
