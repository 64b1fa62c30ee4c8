"""The guides under docs/guides/ run as written: the files they include are the files of the
repository, every ``sh`` block runs and prints what the page shows after it, and their links
resolve; the index (docs/README.md) names every page; bench/node_scenes.py renders its page
from saved results.

An ``sh`` block runs as one bash script from the checkout's root with ``.venv/bin`` first on
the PATH. It must exit 0, or the status a ``# exit status N`` comment in it names. A
``text`` block right after it is its output, merged stdout and stderr: each line of the
page appears in the output, in order; ``...`` within a line stands for any text, and a line
of ``...`` alone for lines left out. A block after ``<!-- guide-run: REASON -->`` is not run
by the generic test (the monitoring guide's is run below, as written, against a live node).
A ``text`` block after ``<!-- guide-numbers: within P % (REASON) -->`` shows figures that
differ from CPU to CPU (a sweep of impacting runs: the last bit of a BLAS sum, which depends
on the CPU's instruction set, moves every later impact): its lines must match word for word
and number for number, each number within P % of the page's. Deadlines are for liveness on a
loaded machine, not figures.
"""
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / 'docs'
GUIDES = sorted((DOCS / 'guides').glob('*.md'))
BIN = Path(sys.executable).parent
INCLUDE = re.compile(r'<!-- include:(\S+) -->\n```\w+\n(.*?)```', flags=re.S)
#: an sh block, the marker before it (if any) and the text block right after it (if any)
SH = re.compile(r'(?:<!-- guide-run: ([^>]*?) -->\n)?```sh\n(.*?)```\n'
                r'(?:\s*\n(?:<!-- guide-numbers: within ([0-9.]+) % \([^>]+\) -->\n)?'
                r'```text\n(.*?)```)?', flags=re.S)


def _env(**extra):
    return dict(os.environ, PATH=f'{BIN}{os.pathsep}{os.environ["PATH"]}',
                AMENT_PREFIX_PATH=os.environ.get('AMENT_PREFIX_PATH', str(BIN.parent)),
                **extra)


def _blocks(marker=None):
    """(page name, script, expected output or None, relative tolerance of its numbers) of the
    guides' sh blocks whose marker is ``marker`` (None: unmarked, the ones the generic test
    runs)."""
    found = []
    for page in GUIDES:
        for mark, script, percent, output in SH.findall(page.read_text()):
            if (mark or None) == marker:
                found.append((page.name, script, output or None,
                              float(percent) / 100.0 if percent else 0.0))
    return found


def _number(word):
    try:
        return float(word.replace(',', ''))
    except ValueError:
        return None


def _same_within(want, line, rel):
    """Whether ``line`` says ``want`` word for word, each number within ``rel`` of it."""
    wanted, words = want.split(), line.split()
    if len(wanted) != len(words):
        return False
    for w, x in zip(wanted, words):
        a, b = _number(w), _number(x)
        if a is None or b is None:
            if w != x:
                return False
        elif abs(a - b) > rel * abs(a):
            return False
    return True


def _shows(expected, actual, rel=0.0):
    """Problems of ``actual`` output against a page's ``expected`` (see the module); with
    ``rel`` > 0, a line without ``...`` matches one that has its words and, within ``rel``
    (relative), its numbers."""
    lines = [ln.rstrip() for ln in actual.splitlines()]
    at = 0
    for want in expected.splitlines():
        if want.strip() in ('', '...'):
            continue
        pattern = re.compile('.*'.join(re.escape(p) for p in want.rstrip().split('...')))
        if rel and '...' not in want:
            def matches(line, want=want):
                return _same_within(want, line, rel)
        else:
            matches = pattern.fullmatch
        hit = next((i for i in range(at, len(lines)) if matches(lines[i])), None)
        if hit is None:
            return f'not printed (in this order): {want!r}'
        at = hit + 1
    return None


def test_included_files_are_the_repositorys():
    included = [(page.name, path, text) for page in GUIDES
                for path, text in INCLUDE.findall(page.read_text())]
    assert {path for _, path, _ in included} >= {'examples/monitoring_node.py',
                                                  'test/test_guide_callbacks.py',
                                                  'examples/my_pump.yaml'}
    for page, path, text in included:
        assert text == (ROOT / path).read_text(), f'{page}: {path} differs from the file'


def test_every_guide_block_is_run_or_says_why_not():
    names = {name for name, *_ in _blocks()}
    assert names >= {'damper-design.md', 'add-a-scene.md', 'testing-callbacks.md'}
    assert [name for name, *_ in _blocks('monitoring')] == ['monitoring-node.md']
    for page in GUIDES:
        text = page.read_text()
        assert text.count('```sh\n') == len(SH.findall(text)), page.name
        # a tolerance comment the pattern did not take would leave its block exact, silently
        assert text.count('<!-- guide-numbers:') == sum(1 for b in SH.findall(text) if b[2])
        for mark, *_ in SH.findall(text):
            assert mark in ('', 'monitoring') or mark.startswith('skip ('), (page.name, mark)


@pytest.mark.parametrize('page,script,output,rel', _blocks(),
                         ids=[f'{name}-{i}' for i, (name, *_) in enumerate(_blocks())])
def test_guide_block_runs_as_written(page, script, output, rel):
    status = re.search(r'# exit status (\d+)', script)
    done = subprocess.run(['bash', '-c', script], cwd=ROOT, env=_env(), timeout=300,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert done.returncode == (int(status.group(1)) if status else 0), (page, done.stdout)
    assert 'Traceback' not in done.stdout, done.stdout
    if output is not None:
        problem = _shows(output, done.stdout, rel)
        assert problem is None, f'{page}: {problem}\n--- printed:\n{done.stdout}'


def test_shows_catches_a_changed_line():
    assert _shows('a 1\n...\nc ... s\n', 'a 1\nb\nc 12 s\n') is None
    assert _shows('a 1\nc ... s\n', 'a 2\nc 12 s\n') is not None
    assert _shows('c ... s\na 1\n', 'a 1\nc 12 s\n') is not None   # order kept


def test_shows_within_a_tolerance_keeps_words_and_bounds_numbers():
    page = '1.7 mil   4.226   3,407\nbest 1.7 mil\n3 runs in ... s\n'
    close = '1.7 mil 4.115 3452\nbest 1.7 mil\n3 runs in 3.04 s\n'
    assert _shows(page, close, 0.05) is None
    assert _shows(page, close) is not None                                 # exact by default
    assert _shows(page, close.replace('4.115', '4.9'), 0.05) is not None   # 16 % off
    assert _shows(page, close.replace('mil', 'mm', 1), 0.05) is not None   # a word changed
    assert _shows(page, close.replace('best', 'worst'), 0.05) is not None
    assert _shows(page, '1.7 mil 4.115\nbest 1.7 mil\n3 runs in 3 s\n', 0.05) is not None


class _Proc:
    """A shell line of the page, run in its own session; its merged output, line by line."""

    def __init__(self, line, env):
        self.lines = []
        self.proc = subprocess.Popen(['bash', '-c', f'exec {line}'], cwd=ROOT, env=env,
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True, start_new_session=True)
        threading.Thread(target=lambda: self.lines.extend(self.proc.stdout),
                         daemon=True).start()

    def wait_for(self, done, timeout):
        end = time.monotonic() + timeout
        while time.monotonic() < end and self.proc.poll() is None and not done(self.lines):
            time.sleep(0.2)
        return done(self.lines)

    def stop(self):
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
        try:
            return self.proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)
            return self.proc.wait()


REPORT = re.compile(r'sim +([0-9.]+) s: +([0-9.]+) rad/s, rms ([0-9.]+) g, 1x ([0-9.]+) g, '
                    r'unbalance x([0-9.]+)')


def _reports(lines):
    return [tuple(float(x) for x in m.groups()) for m in map(REPORT.fullmatch,
                                                            (ln.rstrip() for ln in lines)) if m]


def test_monitoring_guide_runs_as_written():
    """The guide's three shell lines: the node, the monitoring node, the unbalance command.
    The monitoring node prints lines of the page's form, and three times the unbalance at
    full speed gives three times the 1x (the casing is linear there: 2 %)."""
    pytest.importorskip('rclpy')
    from conftest import next_domain_id
    [(page, script, _, _)] = _blocks('monitoring')
    # what it prints: the page's first text block after the commands (prose in between)
    output = re.search(r'guide-run: monitoring.*?```text\n(.*?)```',
                       (DOCS / 'guides' / page).read_text(), flags=re.S).group(1)
    node_line, monitor_line, command_line = [ln.split('  #')[0].strip()
                                             for ln in script.strip().splitlines()]
    assert command_line.startswith('ros2 topic pub')
    env = _env(ROS_DOMAIN_ID=str(next_domain_id()))
    node = _Proc(node_line, env)
    monitor = None
    try:
        assert node.wait_for(lambda ls: any('accelerometers at' in ln for ln in ls), 180.0), \
            ''.join(node.lines)
        monitor = _Proc(monitor_line, env)
        # full speed (2400 rad/s from sim 5 s) over a whole window, twice
        assert monitor.wait_for(lambda ls: sum(r[1] == 2400.0 and r[0] >= 6.5
                                               for r in _reports(ls)) >= 2, 120.0), \
            ''.join(monitor.lines)
        before = _reports(monitor.lines)[-1]
        assert before[4] == 1.0 and before[3] > 0.1   # the casing's 1x at X = 1 (g)
        shapes = [re.compile(re.sub(r'[0-9]+(\\\.[0-9]+)?', r'[0-9.]+', re.escape(ln)))
                  for ln in output.splitlines() if ln.strip()]
        for line in monitor.lines:
            assert any(s.fullmatch(line.rstrip()) for s in shapes), line
        if not (BIN / 'ros2').exists():
            pytest.skip('the ROS 2 command line is not installed (make ros2cli)')
        sent = subprocess.run(['bash', '-c', command_line], cwd=ROOT, env=env, timeout=120,
                              capture_output=True, text=True)
        assert sent.returncode == 0, (sent.stdout, sent.stderr)
        assert monitor.wait_for(lambda ls: any('seen' in ln for ln in ls), 30.0)
        seen = next(i for i, ln in enumerate(monitor.lines) if 'seen' in ln)
        # the window the command arrived in mixes both levels: two more after it
        assert monitor.wait_for(lambda ls: len(_reports(ls[seen:])) >= 2, 60.0), \
            ''.join(monitor.lines)
        after = _reports(monitor.lines[seen:])[1]
        assert after[4] == 3.0 and after[1] == 2400.0
        assert after[3] / before[3] == pytest.approx(3.0, rel=0.02)
        for line in monitor.lines:
            assert any(s.fullmatch(line.rstrip()) for s in shapes), line
    finally:
        if monitor is not None:
            monitor.stop()
        node.stop()
        if (BIN / 'ros2').exists():
            subprocess.run([str(BIN / 'ros2'), 'daemon', 'stop'], env=env,
                           capture_output=True, timeout=60)


def _links(page):
    return [t for t in re.findall(r'\]\(([^)#]+)(?:#[^)]*)?\)', page.read_text())
            if '://' not in t]


def test_guide_index_and_bench_links_resolve():
    pages = [*GUIDES, *sorted((DOCS / 'bench').glob('*.md')), DOCS / 'README.md']
    for page in pages:
        for target in _links(page):
            assert (page.parent / target).exists(), (page.name, target)


def test_index_names_every_page():
    index = DOCS / 'README.md'
    named = {(index.parent / t).resolve() for t in _links(index)}
    pages = [*DOCS.glob('*.md'), *GUIDES, *(DOCS / 'bench').glob('*.md')]
    missing = [p.relative_to(DOCS) for p in pages if p != index and p.resolve() not in named]
    assert not missing, missing
    assert '(docs/README.md)' in (ROOT / 'README.md').read_text()


def test_bench_page_renders_saved_results(tmp_path):
    """``--render`` writes the header once, one row per result and each verdict."""
    ran = {'scene': 'sdof', 'status': 'ran', 'start_s': 1.2, 'rtf_worst': 0.975,
           'rtf_median': 1.0, 'cpu_median': 20.0, 'cpu_peak': 31.0, 'samples_per_s': 2000.0,
           'impacts_per_s': 50.0, 'others_cpu': 3.0, 'steal_percent': None,
           'topics': [{'type': 'sensor_msgs/msg/Imu', 'py_percent': 99.5,
                       'py_lag_max': 0.02, 'py_cpu': 40.0}],
           'monitor': {'ok': True}, 'pass': False, 'why': ['worst RTF 0.975 < 0.98']}
    refused = {'scene': 'hpotp_x10', 'status': 'refused', 'reason': 'offline_only: too big'}
    saved = tmp_path / 'results.json'
    saved.write_text(json.dumps({'date': '2030-01-02', 'machine': 'Some CPU, 2 cores',
                                 'command': 'bench/node_scenes.py --cold', 'load_before': 0.5,
                                 'load': 1.25, 'seconds': 20.0, 'load_hog': False,
                                 'results': [ran, refused]}))
    page = tmp_path / 'page.md'
    done = subprocess.run([sys.executable, str(ROOT / 'bench' / 'node_scenes.py'), '--render',
                           str(saved), '--page', str(page)], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    text = page.read_text()
    assert text.count('2030-01-02') == 1 and text.count('Some CPU, 2 cores') == 1
    assert '`bench/node_scenes.py --cold`' in text and '0.50 before, 1.25 after' in text
    assert ('| sdof | 1.2 | 0.975 | 1.000 | 20.0 | 31.0 | 2000 | 50 | 99.5 | 0.020 | 40 | ok '
            '| FAIL |') in text
    assert '- sdof: FAIL: worst RTF 0.975 < 0.98' in text
    assert '| hpotp_x10 | refused: offline_only: too big |' in text
    assert '| sdof | 3 | - |' in text   # steal not measured: a dash, not 0
