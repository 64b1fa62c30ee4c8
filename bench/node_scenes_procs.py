"""Process handling of bench/node_scenes.py: its children, their CPU, free DDS domains.

:class:`Child` (a subprocess with its stdout lines in a queue and its stderr in a log file),
:class:`CpuSampler` (utime + stime from ``/proc`` every second), the machine's CPU counters
and the hypervisor's steal, the choice of a DDS domain nobody on this machine uses and the
wait for a console script a reinstall may be rewriting. Apart from the driver because none of
it knows what the bench measures: it starts, watches and stops processes on Linux.
"""
from __future__ import annotations

import math
import os
import queue
import signal
import subprocess
import threading
import time

#: the repository: the children's working directory
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


# ---------------------------------------------------------------------------------------
class Child:
    """A subprocess of the bench: stdout lines to a queue (if piped), stderr to a file."""

    def __init__(self, name, argv, env, log_dir, stdin=False, pipe=True):
        self.name = name
        self.err_path = os.path.join(log_dir, f'{name}.log')
        self._err = open(self.err_path, 'w')
        self.lines = queue.Queue()
        self.t_spawn = time.monotonic()
        self.proc = subprocess.Popen(
            argv, env=env, cwd=ROOT, text=True, start_new_session=True,
            stdin=subprocess.PIPE if stdin else subprocess.DEVNULL,
            stdout=subprocess.PIPE if pipe else self._err, stderr=self._err)
        self.pid = self.proc.pid
        if pipe:
            threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.proc.stdout:
            self.lines.put(line.rstrip('\n'))
        self.lines.put(None)

    def get(self, timeout):
        """Next stdout line (str), None at EOF, or raise queue.Empty."""
        return self.lines.get(timeout=timeout)

    def send(self, text):
        try:
            self.proc.stdin.write(text + '\n')
            self.proc.stdin.flush()
        except (BrokenPipeError, OSError, ValueError):
            pass

    def close_stdin(self):
        try:
            self.proc.stdin.close()
        except (BrokenPipeError, OSError, ValueError, AttributeError):
            pass

    def signal(self, sig=signal.SIGINT):
        if self.proc.poll() is None:
            try:
                self.proc.send_signal(sig)
            except ProcessLookupError:
                pass

    def wait(self, timeout):
        """Wait up to ``timeout`` s, then SIGKILL; return the exit status (None if killed)."""
        try:
            return self.proc.wait(timeout=max(timeout, 0.0))
        except subprocess.TimeoutExpired:
            self.proc.kill()
            try:
                self.proc.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                pass
            return None

    def stderr_lines(self):
        self._err.flush()
        try:
            with open(self.err_path, errors='replace') as f:
                return [line.rstrip('\n') for line in f]
        except OSError:
            return []


class CpuSampler:
    """Samples utime + stime of registered processes from /proc every ``period`` s."""

    TICK = os.sysconf('SC_CLK_TCK')

    def __init__(self, period=1.0):
        self.period = period
        self.samples = {}   # pid -> list of (monotonic, cpu s)
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    @classmethod
    def read(cls, pid):
        if pid == 'all':   # the machine: busy time of all cores (/proc/stat)
            try:
                with open('/proc/stat') as f:
                    v = [int(x) for x in f.readline().split()[1:9]]
                return (v[0] + v[1] + v[2] + v[5] + v[6] + v[7]) / cls.TICK
            except (OSError, ValueError, IndexError):
                return None
        try:
            with open(f'/proc/{pid}/stat') as f:
                fields = f.read().rsplit(')', 1)[1].split()
            return (int(fields[11]) + int(fields[12])) / cls.TICK
        except (OSError, IndexError, ValueError):
            return None

    def add(self, pid):
        with self._lock:
            self.samples.setdefault(pid, [])
        self._sample(pid)

    def _sample(self, pid):
        cpu = self.read(pid)
        if cpu is not None:
            with self._lock:
                self.samples[pid].append((time.monotonic(), cpu))

    def _run(self):
        while not self._stop.wait(self.period):
            with self._lock:
                pids = list(self.samples)
            for pid in pids:
                self._sample(pid)

    def stop(self):
        self._stop.set()
        self._thread.join(timeout=2.0)

    def windows(self, pid, t0, t1):
        """Per-interval CPU (% of one core) of samples within [t0, t1], and the mean."""
        with self._lock:
            s = [x for x in self.samples.get(pid, []) if t0 - 1e-6 <= x[0] <= t1 + 1e-6]
        if len(s) < 2:
            return [], math.nan
        per = [100.0 * (b[1] - a[1]) / (b[0] - a[0]) for a, b in zip(s, s[1:])
               if b[0] - a[0] > 0.2]
        return per, 100.0 * (s[-1][1] - s[0][1]) / (s[-1][0] - s[0][0])


# ---------------------------------------------------------------------------------------
def domain_in_use(domain):
    """True when a local UDP port of the domain's RTPS range (7400 + 250 x domain + 0..249,
    the ports Fast DDS and Cyclone DDS derive from it) is bound: someone else's participant."""
    base = 7400 + 250 * domain
    for path in ('/proc/net/udp', '/proc/net/udp6'):
        try:
            with open(path) as f:
                for line in f.readlines()[1:]:
                    port = int(line.split()[1].rsplit(':', 1)[1], 16)
                    if base <= port < base + 250:
                        return True
        except (OSError, IndexError, ValueError):
            pass
    return False


def pick_domain(start):
    """The first domain from ``start`` (cycling over 101..230) nobody on this machine uses."""
    for k in range(130):
        d = 101 + (start - 101 + k) % 130
        if not domain_in_use(d):
            return d
    return start


def settled_script(paths, timeout=60.0):
    """The first of ``paths`` that exists, is not empty and has not changed for 2 s (a
    reinstall of the venv rewrites the console scripts), waiting up to ``timeout`` s; None."""
    end = time.monotonic() + timeout
    while True:
        for path in paths:
            try:
                st = os.stat(path)
            except OSError:
                continue
            if st.st_size > 0 and time.time() - st.st_mtime > 2.0:
                return path
        if time.monotonic() > end:
            return None
        time.sleep(0.5)


def _cpu_ticks():
    """The machine's CPU time counters (``/proc/stat``'s first line: user ... steal)."""
    try:
        with open('/proc/stat') as f:
            return [int(x) for x in f.readline().split()[1:9]]
    except (OSError, ValueError):
        return None


def _steal_percent(before, after):
    """Share of the CPU time the hypervisor gave to other guests in between (%): a virtual
    machine's cores taken away while its own load looks light."""
    if not before or not after:
        return math.nan
    d = [b - a for a, b in zip(before, after)]
    return 100.0 * d[7] / sum(d) if sum(d) > 0 else math.nan
