"""The README's first screens stay true: the examples it includes are the files in examples/,
they run as written against a live node and print what the README says, and the start-up
line, the topic list and the monitor's lines it shows are what the node and monitor print.

One ``vibration_node`` (default scene, as ``make run`` starts it) runs for the module in its
own process on its own DDS domain; each example and the monitor run beside it as
subprocesses. Deadlines (60 s, 180 s for a start that compiles the kernels) are for liveness
on a loaded machine, not figures.
"""
import math
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / 'README.md'
BIN = Path(sys.executable).parent
STARTED = 'accelerometers at'
#: where the README includes a file of the repository verbatim
INCLUDE = re.compile(r'<!-- include:(\S+) -->\n```python\n(.*?)```', flags=re.S)


def _included():
    return INCLUDE.findall(README.read_text())


def _text_blocks(after):
    """The ``text`` code block that follows the README line containing ``after``."""
    text = README.read_text()
    return re.search(re.escape(after) + r'.*?```text\n(.*?)```', text, flags=re.S).group(1)


class Proc:
    """A subprocess whose merged output a thread collects (lines, as they come)."""

    def __init__(self, args, env):
        self.lines = []
        self.proc = subprocess.Popen(args, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True,
                                     start_new_session=True)
        threading.Thread(target=lambda: self.lines.extend(self.proc.stdout),
                         daemon=True).start()

    def wait_for(self, done, timeout):
        """Wait until ``done(lines)`` or the process exits or ``timeout`` (s) passes."""
        end = time.monotonic() + timeout
        while time.monotonic() < end and self.proc.poll() is None and not done(self.lines):
            time.sleep(0.2)
        return done(self.lines)

    def interrupt(self):
        """Ctrl-C, as a user stops it; the exit status (killed after 30 s)."""
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
        try:
            return self.proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()
            raise


@pytest.fixture(scope='module')
def node():
    """``vibration_node`` as ``make run`` starts it, on a domain of its own: (env, start-up
    line)."""
    pytest.importorskip('rclpy')
    from conftest import next_domain_id
    env = dict(os.environ, ROS_DOMAIN_ID=str(next_domain_id()),
               AMENT_PREFIX_PATH=os.environ.get('AMENT_PREFIX_PATH', str(BIN.parent)))
    proc = Proc([str(BIN / 'vibration_node')], env)
    try:
        assert proc.wait_for(lambda lines: any(STARTED in ln for ln in lines), 180.0), \
            ''.join(proc.lines)
        yield env, next(ln for ln in proc.lines if STARTED in ln)
    finally:
        proc.interrupt()


def test_readme_includes_the_example_files_verbatim():
    included = _included()
    assert {path for path, _ in included} == {'examples/batch_subscriber.py',
                                              'examples/imu_subscriber.py'}
    for path, code in included:
        assert code == (ROOT / path).read_text(), f'README block differs from {path}'


def test_readme_shows_the_start_up_line(node):
    _, line = node
    shown = _text_blocks('## What you see').strip()
    assert re.sub(r'^\[INFO\] \[[0-9.]+\]', '[INFO] [...]', line.strip()) == shown


def test_readme_topic_list_is_the_default_scenes(node):
    """The ``ros2 topic list`` block: the topics of the graph the node makes (what ``ros2
    topic list`` asks the graph for), no more, no fewer."""
    import rclpy
    env, _ = node
    listed = set(re.search(r'<!-- topic-list:start -->\n```text\n(.*?)```',
                           README.read_text(), flags=re.S).group(1).split())
    domain = int(env['ROS_DOMAIN_ID'])
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain)
    probe = rclpy.create_node('topic_lister', context=ctx)
    try:
        end = time.monotonic() + 60.0
        seen = set()
        while time.monotonic() < end and not listed <= seen:
            time.sleep(0.2)
            seen = {name for name, _ in probe.get_topic_names_and_types()}
        assert seen == listed, (sorted(seen - listed), sorted(listed - seen))
    finally:
        probe.destroy_node()
        rclpy.try_shutdown(context=ctx)


def _pattern(shown):
    """A README output line as a regex: its numbers and ``[...]`` stand for any."""
    parts = re.split(r'(\[\.\.\.\]|-?\d+(?:\.\d+)?(?:e[-+]?\d+)?)', shown)
    return '^' + ''.join(
        r'\[[0-9.]+\]' if p == '[...]' else r'-?[0-9.]+(?:e[-+]?\d+)?' if i % 2 else
        re.escape(p) for i, p in enumerate(parts)) + '$'


def test_readme_monitor_lines_are_the_monitors(node):
    env, _ = node
    shown = [ln for ln in _text_blocks('impact_damper_monitor').splitlines() if ln]
    assert len(shown) == 2
    patterns = [re.compile(_pattern(ln)) for ln in shown]
    proc = Proc([str(BIN / 'impact_damper_monitor')], env)
    try:
        ok = proc.wait_for(lambda lines: all(any(p.match(ln.rstrip('\n')) for ln in lines)
                                             for p in patterns), 60.0)
    finally:
        status = proc.interrupt()
    assert ok, (shown, ''.join(proc.lines))
    assert status == 0, ''.join(proc.lines)


@pytest.mark.parametrize('path, topic, rate_at', [
    ('examples/batch_subscriber.py', 'accel/hpotp_casing_bottom/batch', 1),
    ('examples/imu_subscriber.py', 'accel/hpotp_casing_bottom', 2)])
def test_example_prints_the_stream(node, path, topic, rate_at):
    """Three lines or more, each: the topic, the node's rate (from its start-up line) within
    5 %, a finite non-zero rms; then Ctrl-C ends it with status 0. The Imu is best effort: its
    Python reader loses samples when the machine is loaded (every second of a run in a
    fresh clone's make test beside another suite), which only lowers a count; so for it
    every count is above 0 and at most 5 % over the rate. What it receives under load is a
    bench figure (bench/node_scenes.py), not this test's."""
    env, line = node
    rates = re.search(r'at (\d+) Hz \(per-sample Imu at (\d+) Hz\)', line).groups()
    rate = float(rates[rate_at - 1])
    form = re.compile(rf'^{re.escape(topic)}: (\d+) samples/s, rms ay (\S+) m/s\^2$')
    def within(line):
        return abs(float(form.match(line).group(1)) / rate - 1.0) <= 0.05

    def enough(lines):
        printed = [ln for ln in lines if form.match(ln)]
        return len(printed) >= 3 and (rate_at == 2 or any(within(ln) for ln in printed))

    proc = Proc([sys.executable, str(ROOT / path)], env)
    try:
        proc.wait_for(enough, 60.0)
    finally:
        status = proc.interrupt()
    out = ''.join(proc.lines)
    assert status == 0 and 'Traceback' not in out, out
    found = [form.match(ln.rstrip('\n')) for ln in proc.lines]
    assert len(found) >= 3 and all(found), out   # every line has the README's form
    counts = np.array([float(m.group(1)) for m in found])
    rms = np.array([float(m.group(2)) for m in found])
    if rate_at == 1:   # reliable: every sample arrives
        assert np.all(np.abs(counts / rate - 1.0) <= 0.05), (rate, out)
    else:
        assert np.all((counts > 0) & (counts <= 1.05 * rate)), (rate, out)
    assert all(math.isfinite(r) and r > 0 for r in rms), out


def _layouts():
    from impact_damper_sim.recording import batches as b
    return {'accel/<name>/batch and /truth': (b.ACCEL_FIELDS, b.ACCEL_POINT_STEP),
            'impacts': (b.IMPACT_FIELDS, b.IMPACT_POINT_STEP),
            'rotor/tach': (b.TACH_FIELDS, b.TACH_POINT_STEP),
            'rotor/keyphasor': (b.KEYPHASOR_FIELDS, b.KEYPHASOR_POINT_STEP)}


@pytest.mark.parametrize('topic', sorted(_layouts()))
def test_rows_round_trip_every_batch_layout(topic):
    """The node's packer -> CDR -> rclpy -> batch_rows/batch_columns/batch_times: the same
    values, exactly, under the layout's own field names."""
    pytest.importorskip('rclpy')
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import PointCloud2

    from impact_damper_sim.recording.batches import BatchEncoder, dtype_of
    from impact_damper_sim.ros.rows import batch_columns, batch_rows, batch_times
    fields, step = _layouts()[topic]
    rng = np.random.default_rng(7)
    rows = np.zeros(37, dtype_of(fields, step))
    for name in rows.dtype.names:
        rows[name] = rng.integers(0, 2**31, rows.size) if rows.dtype[name].kind == 'u' \
            else rng.normal(size=rows.size)
    rows['t'] = np.arange(rows.size) / 2000.0
    msg = deserialize_message(BatchEncoder('frame', fields, step).encode(12_345_000_000, rows),
                              PointCloud2)
    got = batch_rows(msg)
    assert got.dtype.names == tuple(f[0] for f in fields)
    for name in rows.dtype.names:
        assert got.dtype[name] == rows.dtype[name]
        np.testing.assert_array_equal(got[name], rows[name])
    columns = batch_columns(msg)
    assert list(columns) == list(rows.dtype.names)
    np.testing.assert_array_equal(columns[fields[-1][0]], rows[fields[-1][0]])
    # stamp + t: exact to the float64 rounding of a sum near 12.3 s
    np.testing.assert_allclose(batch_times(msg), 12.345 + rows['t'], rtol=0, atol=1e-14)


def test_rows_decode_by_name_in_another_field_order():
    """A PointCloud2 with other offsets and field order (as another driver might write it)
    decodes by name, not by position."""
    pytest.importorskip('rclpy')
    from sensor_msgs.msg import PointCloud2, PointField

    from impact_damper_sim.ros.rows import batch_columns, batch_rows
    t, ay = np.array([0.0, 0.5e-3, 1e-3]), np.array([1.5, -2.0, 0.25])
    data = np.zeros(3, np.dtype([('ay', '<f4'), ('pad', '<f4'), ('t', '<f8')]))
    data['ay'], data['t'] = ay, t
    msg = PointCloud2(height=1, width=3, point_step=16, row_step=48, is_bigendian=False,
                      is_dense=True, data=data.tobytes(), fields=[
                          PointField(name='t', offset=8, datatype=PointField.FLOAT64, count=1),
                          PointField(name='ay', offset=0, datatype=PointField.FLOAT32,
                                     count=1)])
    rows = batch_rows(msg)
    assert rows.dtype.names == ('t', 'ay')
    np.testing.assert_array_equal(rows['t'], t)
    np.testing.assert_array_equal(rows['ay'], ay.astype(np.float32))
    assert batch_columns(msg)['ay'].dtype == np.float32


def test_rows_refuse_a_short_buffer():
    pytest.importorskip('rclpy')
    from sensor_msgs.msg import PointCloud2, PointField

    from impact_damper_sim.ros.rows import batch_rows
    msg = PointCloud2(height=1, width=4, point_step=8, data=bytes(24), fields=[
        PointField(name='t', offset=0, datatype=PointField.FLOAT64, count=1)])
    with pytest.raises(ValueError, match='4 rows of 8 need 32'):
        batch_rows(msg)


def test_rows_doctest():
    """The helper's docstring example runs (a packed batch decoded through rclpy)."""
    pytest.importorskip('rclpy')
    import doctest

    import impact_damper_sim.ros.rows as rows
    failed, attempted = doctest.testmod(rows, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert failed == 0 and attempted >= 7
