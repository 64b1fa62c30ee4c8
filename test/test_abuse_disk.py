"""Issue 35, items 2 and 5 on the callers' side: disk faults and kills, each reproduced first.

* ``study record`` on a full disk (a 256 KiB tmpfs of the test's own, else a child with
  ``RLIMIT_FSIZE``), on ``/dev/full``, with an I/O error, with its directory removed while it
  writes, and into a read-only or missing directory: one line on stderr naming the file and
  the error, a non-zero exit status, ``--json`` saying it, and what the line says is on disk
  is what ``study recover`` finds;
* ``study dataset`` on a full disk: the run failed in the manifest with its reason, the data
  set stopped, and a second run after space was made records the rest;
* the node: one ERROR line when the disk fails, never "recorded N messages" for an
  unfinished or vanished file, ``~/record false`` answering failure;
* ``study dataset`` killed (SIGKILL, SIGTERM): no process of its session left.

No wall-clock assertion: waits poll with generous deadlines.
"""
import contextlib
import errno
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time

import pytest

from impact_damper_sim.cli.study import main

#: ``study record`` / ``study dataset``: the log (or a run's log) could not be written
EXIT_WRITE = 4
NO_SPACE = os.strerror(errno.ENOSPC)
TOO_LARGE = os.strerror(errno.EFBIG)


# --- a small file system of the test's own -------------------------------------------------

class SmallDisk:
    """Where a test can fill a disk: ``dir`` on a small tmpfs (``preexec`` None), or a plain
    directory with ``preexec`` limiting a child's file size (``RLIMIT_FSIZE``)."""

    def __init__(self, directory, preexec=None, reason=NO_SPACE, mounted=False):
        self.dir, self.preexec, self.reason, self.mounted = directory, preexec, reason, mounted


def _mount(directory, options):
    if os.geteuid() != 0 or not shutil.which('mount'):
        return 'not root (mounting a tmpfs needs CAP_SYS_ADMIN)'
    done = subprocess.run(['mount', '-t', 'tmpfs', '-o', options, 'tmpfs', str(directory)],
                          capture_output=True, text=True)
    return None if done.returncode == 0 else (done.stderr.strip() or 'mount failed')


def _umount(directory):
    subprocess.run(['umount', '-l', str(directory)], capture_output=True)


def _limit_file_size(limit=256 * 1024):
    import resource
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)   # so that the write fails with EFBIG
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))


def _small_disk(tmp_path, kib):
    directory = tmp_path / 'small'
    directory.mkdir()
    why = _mount(directory, f'size={kib}k')
    if why is None:
        try:
            yield SmallDisk(directory, mounted=True)
        finally:
            _umount(directory)
        return
    try:
        import resource  # noqa: F401  (the fallback needs it)
    except ImportError:
        pytest.skip(f'no tmpfs ({why}) and no RLIMIT_FSIZE (no resource module)')
    yield SmallDisk(directory, preexec=lambda: _limit_file_size(kib * 1024),
                    reason=TOO_LARGE)


@pytest.fixture
def small_disk(tmp_path):
    """A 256 KiB tmpfs (unmounted after the test), or a child's ``RLIMIT_FSIZE``: less than
    one 768 KiB chunk of ``study record`` fits."""
    yield from _small_disk(tmp_path, 256)


@pytest.fixture
def disk_2m(tmp_path):
    """As :func:`small_disk`, 2 MiB: a few chunks fit, then the disk is full."""
    yield from _small_disk(tmp_path, 2048)


@pytest.fixture
def read_only_dir(tmp_path):
    """A directory no file can be created in: a read-only tmpfs (root), else mode 0555."""
    directory = tmp_path / 'ro'
    directory.mkdir()
    if os.geteuid() != 0:
        directory.chmod(0o555)
        yield directory, os.strerror(errno.EACCES)
        directory.chmod(0o755)
        return
    why = _mount(directory, 'ro,size=64k')
    if why is not None:
        pytest.skip(f'root ignores file modes and a read-only tmpfs cannot be mounted: {why}')
    try:
        yield directory, os.strerror(errno.EROFS)
    finally:
        _umount(directory)


def _study(args, preexec=None, timeout=300):
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    return subprocess.run([sys.executable, '-m', 'impact_damper_sim.cli.study', *args],
                          capture_output=True, text=True, timeout=timeout, env=env,
                          preexec_fn=preexec)


def _one_line(stderr):
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert len(lines) == 1, stderr
    assert 'Traceback' not in stderr
    return lines[0]


def _recover_count(path, tmp_path):
    """Messages ``study recover`` gets from ``path`` (into tmp_path, not the small disk)."""
    from impact_damper_sim.recording import recover
    return recover(path, tmp_path / 'recovered.mcap', overwrite=True).messages


# --- study record ------------------------------------------------------------------------

def test_record_on_a_full_disk_ends_in_one_line_and_exit_4(disk_2m, tmp_path):
    """It exited 0 with its normal summary (and JSON ``failure: None``) before."""
    out = disk_2m.dir / 'run.mcap'
    done = _study(['record', 'sdof', '--duration', '10 s', '--out', str(out)],
                  disk_2m.preexec)
    assert done.returncode == EXIT_WRITE, done.stderr
    line = _one_line(done.stderr)
    assert done.stdout == ''   # no summary of a run whose log is not there
    assert str(out) in line and disk_2m.reason in line, line
    assert 'unfinished' in line and f'study recover {out}' in line, line
    # what the line says reached the file is what recover finds in it
    said = int(re.search(r'([\d,]+) messages? in complete chunks', line)[1].replace(',', ''))
    assert _recover_count(out, tmp_path) == said > 0


def test_record_on_a_disk_too_small_for_one_chunk(small_disk, tmp_path):
    """Less than one 768 KiB chunk fits: the line counts only what is in complete chunks
    (it said "up to 1,880 messages (0.26 MB) reached it" at first, and recover found 1)."""
    out = small_disk.dir / 'run.mcap'
    done = _study(['record', 'sdof', '--duration', '5 s', '--out', str(out)],
                  small_disk.preexec)
    assert done.returncode == EXIT_WRITE, done.stderr
    line = _one_line(done.stderr)
    assert str(out) in line and small_disk.reason in line, line
    found = _recover_count(out, tmp_path)
    if 'no complete chunk' in line:
        assert found == 0 and 'study recover' not in line, line
    else:
        said = re.search(r'([\d,]+) messages? in complete chunks', line)[1]
        assert found == int(said.replace(',', '')), line


def test_record_json_says_the_log_is_unfinished(small_disk):
    out = small_disk.dir / 'run.mcap'
    done = _study(['record', 'sdof', '--duration', '5 s', '--out', str(out), '--json'],
                  small_disk.preexec)
    assert done.returncode == EXIT_WRITE, done.stderr
    _one_line(done.stderr)
    result = json.loads(done.stdout)
    assert result['finished'] is False
    assert small_disk.reason in result['write_error'] and str(out) in result['write_error']
    assert result['sim_time_s'] < 5.0   # stopped at the error, not stepped on for nothing


@pytest.mark.skipif(not os.path.exists('/dev/full'), reason='needs /dev/full')
def test_record_to_dev_full_through_a_symlink(tmp_path):
    """``--out`` a symlink to /dev/full with --overwrite: exit 0, "0 messages" before."""
    out = tmp_path / 'full.mcap'
    out.symlink_to('/dev/full')
    done = _study(['record', 'sdof', '--duration', '200 ms', '--out', str(out),
                   '--overwrite'])
    assert done.returncode == EXIT_WRITE, done.stderr
    line = _one_line(done.stderr)
    assert str(out) in line and NO_SPACE in line and 'nothing reached' in line, line
    assert 'study recover' not in line   # there is nothing to recover


def test_record_into_a_missing_directory_is_refused_in_one_line(tmp_path):
    """A traceback (FileNotFoundError from the writer) and exit 1 before."""
    out = tmp_path / 'missing' / 'run.mcap'
    done = _study(['record', 'sdof', '--duration', '200 ms', '--out', str(out)])
    assert done.returncode == 2, done.stderr
    line = _one_line(done.stderr)
    assert str(out) in line and os.strerror(errno.ENOENT) in line, line
    assert not out.parent.exists()


def test_record_into_a_read_only_directory_is_refused_in_one_line(read_only_dir):
    """A traceback (``OSError: [Errno 30]``) and exit 1 before."""
    directory, reason = read_only_dir
    out = directory / 'run.mcap'
    done = _study(['record', 'sdof', '--duration', '200 ms', '--out', str(out)])
    assert done.returncode == 2, done.stderr
    line = _one_line(done.stderr)
    assert str(out) in line and reason in line, line


def _fail_writes_after(monkeypatch, calls, exc):
    """Make the MCAP writer's file raise ``exc`` from its ``calls``-th write on."""
    from impact_damper_sim.recording import rosbag2_mcap
    raw = getattr(rosbag2_mcap, '_RawFile', None)
    if raw is None:
        pytest.skip("the MCAP writer has no _RawFile to inject an I/O error into")
    real = raw.write
    count = [0]

    def write(self, data):
        count[0] += 1
        if count[0] >= calls:
            raise exc
        return real(self, data)

    monkeypatch.setattr(raw, 'write', write)


def test_record_with_an_io_error(tmp_path, monkeypatch, capsys):
    out = tmp_path / 'eio.mcap'
    _fail_writes_after(monkeypatch, 6, OSError(errno.EIO, os.strerror(errno.EIO)))
    status = main(['record', 'sdof', '--duration', '2 s', '--out', str(out)])
    captured = capsys.readouterr()
    assert status == EXIT_WRITE
    line = _one_line(captured.err)
    assert str(out) in line and os.strerror(errno.EIO) in line, line
    assert captured.out == ''


def test_record_whose_directory_is_removed_while_it_writes(tmp_path, monkeypatch, capsys):
    """The file is gone with its directory: the run says so (and that nothing is left)."""
    from impact_damper_sim.recording import Rosbag2McapWriter
    directory = tmp_path / 'gone'
    directory.mkdir()
    out = directory / 'run.mcap'
    real = Rosbag2McapWriter.write
    count = [0]

    def write(self, *args):
        count[0] += 1
        if count[0] == 200:
            shutil.rmtree(directory)
        return real(self, *args)

    monkeypatch.setattr(Rosbag2McapWriter, 'write', write)
    status = main(['record', 'sdof', '--duration', '1 s', '--out', str(out)])
    captured = capsys.readouterr()
    assert status == EXIT_WRITE
    line = _one_line(captured.err)
    assert str(out) in line and 'no longer exists' in line, line
    assert 'study recover' not in line


# --- study dataset on a full disk ---------------------------------------------------------

DATASET_SPEC = """\
scene: sdof
duration: {duration}
grid:
  impactors.0.cor: [0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95]
"""


def _spec(tmp_path, duration='1 s'):
    spec = tmp_path / 'spec.yaml'
    spec.write_text(DATASET_SPEC.format(duration=duration))
    return spec


def test_dataset_on_a_full_disk_stops_and_marks_the_run_failed(disk_2m, tmp_path):
    """Before, each run failed alone and the data set went on with the next (a full disk
    fails them all), and the CLI exited 1 listing every run."""
    spec = _spec(tmp_path)
    out = disk_2m.dir / 'data'
    done = _study(['dataset', str(spec), '--out', str(out), '--workers', '2'],
                  disk_2m.preexec)
    assert done.returncode == EXIT_WRITE, done.stderr
    line = _one_line(done.stderr)
    assert disk_2m.reason in line and str(out) in line and 'stopped' in line, line
    doc = json.loads((out / 'manifest.json').read_text())
    assert doc['runs_planned'] == 8
    failed = [r for r in doc['runs'] if r['status'] == 'failed']
    assert failed and len(doc['runs']) < 8   # stopped: not every run was tried
    for row in failed:
        assert row['error'].startswith('disk error: ') and disk_2m.reason in row['error']
    # no unfinished log under a run's name, and the .part files were removed (space)
    assert not list((out / 'runs').glob('*.part'))
    for row in doc['runs']:
        if row['status'] == 'ok':
            assert (out / row['file']).is_file()
    if not disk_2m.mounted:
        return
    # space made: the same command records the rest, the disk-failed runs included
    subprocess.run(['mount', '-o', 'remount,size=8m', str(disk_2m.dir)], check=True)
    again = _study(['dataset', str(spec), '--out', str(out), '--workers', '2'])
    assert again.returncode == 0, again.stderr
    doc = json.loads((out / 'manifest.json').read_text())
    assert [r['status'] for r in doc['runs']] == ['ok'] * 8


def test_dataset_gather_into_a_full_disk_stops_in_one_line(small_disk, tmp_path):
    """It blamed each part's log ("bad log ... OSError: No space left on device") and went on
    copying, then failed writing the manifest, before."""
    from impact_damper_sim.studies.dataset import run_dataset
    spec = tmp_path / 'spec.yaml'
    spec.write_text('scene: sdof\nduration: 1 s\ngrid:\n  impactors.0.cor: [0.5, 0.7]\n')
    part = tmp_path / 'part'
    assert run_dataset(str(spec), str(part), executor='serial')['failed'] == 0
    out = small_disk.dir / 'merged'
    done = _study(['dataset', '--gather', str(part), '--out', str(out)], small_disk.preexec)
    assert done.returncode == EXIT_WRITE, done.stderr
    line = _one_line(done.stderr)
    assert 'stopped by a disk error' in line and small_disk.reason in line, line
    assert str(out) in line
    assert not list((out / 'runs').glob('*.part'))


# --- killing study dataset ---------------------------------------------------------------

def _session_members(sid):
    """Pids of the live processes of session ``sid`` (zombies excluded)."""
    members = []
    for name in os.listdir('/proc'):
        if not name.isdigit():
            continue
        try:
            with open(f'/proc/{name}/stat') as f:
                fields = f.read().rsplit(')', 1)[1].split()
        except OSError:
            continue
        if int(fields[3]) == sid and fields[0] != 'Z':   # state, ppid, pgrp, session
            members.append(int(name))
    return members


def _start_dataset(tmp_path):
    spec = tmp_path / 'spec.yaml'
    spec.write_text(DATASET_SPEC.format(duration='60 s'))
    out = tmp_path / 'data'
    proc = subprocess.Popen(
        [sys.executable, '-m', 'impact_damper_sim.cli.study', 'dataset', str(spec), '--out',
         str(out), '--workers', '2'], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, start_new_session=True)
    end = time.monotonic() + 120
    while time.monotonic() < end:   # a worker is recording (its .part is growing)
        parts = list((out / 'runs').glob('*.part')) if (out / 'runs').is_dir() else []
        if parts and len(_session_members(proc.pid)) >= 3:
            return proc, out
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.1)
    raise AssertionError('no worker started recording within 120 s')


def _gone_after(sid, deadline=10.0):
    """Seconds until no process of session ``sid`` is left (None: some still are)."""
    start = time.monotonic()
    while time.monotonic() - start < deadline:
        if not _session_members(sid):
            return time.monotonic() - start
        time.sleep(0.02)
    return None


def _kill_session(sid):
    for pid in _session_members(sid):
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGKILL)


@pytest.mark.skipif(not os.path.isdir('/proc'), reason='scans /proc for the session')
def test_sigkill_of_dataset_leaves_no_process(tmp_path, record_property):
    """Its forkserver, resource tracker and 2 workers lived on (parent 1) and recorded the
    remaining runs into files no manifest lists, before."""
    proc, out = _start_dataset(tmp_path)
    try:
        proc.kill()
        proc.wait()
        seconds = _gone_after(proc.pid)
        left = _session_members(proc.pid)
    finally:
        _kill_session(proc.pid)
    record_property('seconds_until_no_process', seconds)
    print(f'SIGKILL: no process left after {seconds} s')
    assert seconds is not None, f'still alive 10 s after SIGKILL: {left}'


@pytest.mark.skipif(not os.path.isdir('/proc'), reason='scans /proc for the session')
@pytest.mark.parametrize('sig', [signal.SIGTERM, signal.SIGINT])
def test_sigterm_and_sigint_of_dataset_stop_it_cleanly(tmp_path, record_property, sig):
    proc, out = _start_dataset(tmp_path)
    try:
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=30)
        seconds = _gone_after(proc.pid)
        left = _session_members(proc.pid)
    finally:
        _kill_session(proc.pid)
    record_property('seconds_until_no_process', seconds)
    print(f'{signal.Signals(sig).name}: no process left {seconds} s after the parent exited')
    assert seconds is not None, f'still alive 10 s after the parent exited: {left}'
    assert proc.returncode == 128 + sig, err
    line = _one_line(err)
    assert 'interrupted' in line and signal.Signals(sig).name in line, line
    json.loads((out / 'manifest.json').read_text())   # a readable manifest
    assert not list((out / 'runs').glob('*.part'))     # the runs in progress: removed


# --- the node -----------------------------------------------------------------------------

def _node(ros_context, path, **extra):
    from rclpy.parameter import Parameter

    from impact_damper_sim.ros.vibration_node import VibrationNode
    params = [Parameter('scene', value='sdof'), Parameter('record', value=str(path))]
    params += [Parameter(k, value=v) for k, v in extra.items()]
    node = VibrationNode(context=ros_context, parameter_overrides=params)
    logged = []
    real = node._log

    def log(level, text, *args, **kwargs):
        logged.append((level, text))
        return real(level, text, *args, **kwargs)

    node._log = log
    return node, logged


def _spin_until(executor, condition, timeout=30.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end and not condition():
        executor.spin_once(timeout_sec=0.02)
    return condition()


@pytest.mark.ros
def test_node_logs_a_disk_error_once_at_error_and_never_claims_the_file(ros_context,
                                                                        small_disk):
    """Before: /diagnostics WARN only, no log line, and at shutdown INFO "recorded 4616
    messages to node.mcap" for an unfinished file."""
    pytest.importorskip('rclpy')
    from rclpy.executors import SingleThreadedExecutor
    from std_srvs.srv import SetBool
    if small_disk.mounted:
        path, overwrite = small_disk.dir / 'node.mcap', False
    elif os.path.exists('/dev/full'):
        path, overwrite = '/dev/full', True
    else:
        pytest.skip('no tmpfs of our own and no /dev/full: no disk to fill')
    node, logged = _node(ros_context, path, record_overwrite=overwrite)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    try:
        # logged when it happens, from the writer thread, before anyone stops the recording
        assert _spin_until(ex, lambda: any(level == 'error' for level, _ in logged)), logged
        errors = [text for level, text in logged if level == 'error']
        assert len(errors) == 1 and str(path) in errors[0] and NO_SPACE in errors[0], errors
        t = node.live.t
        assert _spin_until(ex, lambda: node.live.t > t + 0.3)   # the simulation goes on
        res = node.on_record_request(SetBool.Request(data=False), SetBool.Response())
        assert not res.success and NO_SPACE in res.message and str(path) in res.message
    finally:
        node.destroy_node()
    texts = [text for _, text in logged]
    assert not any(text.startswith('recorded ') for text in texts), texts
    assert len([1 for level, _ in logged if level == 'error']) == 1, logged
    warned = [text for level, text in logged if level == 'warning' and 'unfinished' in text]
    assert warned, texts
    if small_disk.mounted:   # what it says is there, and how to get it back
        assert 'study recover' in warned[0], warned


@pytest.mark.ros
def test_node_record_false_after_its_directory_was_removed(ros_context, tmp_path):
    """``~/record false`` answered success, "recorded 18815 messages to a.mcap", for a file
    that did not exist, before."""
    pytest.importorskip('rclpy')
    from rclpy.executors import SingleThreadedExecutor
    from std_srvs.srv import SetBool
    directory = tmp_path / 'rec'
    directory.mkdir()
    path = directory / 'a.mcap'
    node, logged = _node(ros_context, path)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    try:
        assert _spin_until(ex, lambda: path.exists() and path.stat().st_size > 50_000)
        shutil.rmtree(directory)
        _spin_until(ex, lambda: False, timeout=0.5)
        res = node.on_record_request(SetBool.Request(data=False), SetBool.Response())
    finally:
        node.destroy_node()
    assert not res.success, res.message
    assert str(path) in res.message and 'no longer exists' in res.message, res.message
    texts = [text for _, text in logged]
    assert not any(text.startswith('recorded ') for text in texts), texts
    errors = [text for level, text in logged if level == 'error']
    assert len(errors) == 1 and 'no longer exists' in errors[0], logged
