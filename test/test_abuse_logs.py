"""Issue 35, the log items: each reproduced first by a test here, then fixed.

* definitions survive a corrupt chunk: a crashed log (no summary) with one bad byte in any
  one chunk loses that chunk's messages and no others (it lost them all: the schema and
  channel records were only inside chunk 0), and ``study recover`` exits non-zero when it
  keeps nothing;
* one writer per file: a second writer of a log being written is refused in one line naming
  the holder, overwrite or not, and the first log is intact;
* the writer's contract for its callers: opening errors are one-line ``OSError``\\ s, and
  after ``close()`` ``error`` is set whenever the file is not a finished, readable log
  (deleted or moved while written, disk full); ``finished`` says it is.

Payloads are ``std_msgs/msg/Float64`` CDR written by hand (no rclpy needed): message ``i``
holds ``float(i)`` and has log time ``T0 + i``, so a chunk's time range names its messages.
"""
import errno
import json
import os
import shutil
import signal
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from impact_damper_sim.cli.study import main as study_main
from impact_damper_sim.recording import AsyncRecorder, Rosbag2McapWriter, recover

HERE = Path(__file__).resolve().parent
os.environ.setdefault('AMENT_PREFIX_PATH', sys.prefix)   # the venv holds the .msg files

T0 = 1_700_000_000_000_000_000   # ns since the epoch
FLOAT64 = 'std_msgs/msg/Float64'
TOPICS = [f'/accel/s{k}' for k in range(1, 8)]   # 7 channels, as in the probe


def _payload(i):
    return b'\x00\x01\x00\x00' + struct.pack('<d', float(i))


def _messages(path):
    """Return the set of (topic, log time, payload) in a finished file (mcap's own reader)."""
    from mcap.reader import make_reader
    with open(path, 'rb') as f:
        reader = make_reader(f)
        assert reader.get_summary() is not None, f'{path} is not a finished log'
        return {(c.topic, m.log_time, m.data)
                for _, c, m in reader.iter_messages(log_time_order=False)}


def _crashed_log(tmp_path, n=700, late_after=None, chunk_size=2048):
    """Record ``n`` messages round-robin on TOPICS (registered up front, as the node and
    ``study record`` do) in small chunks; return (crashed bytes, finished file, chunk
    indexes in file order). The crashed bytes are the file as a SIGKILL after the last
    flush leaves it: everything but the summary. With ``late_after``, topic ``/late`` is
    registered after message ``late_after`` and takes every third message from there."""
    path = tmp_path / 'log.mcap'
    writer = Rosbag2McapWriter(path, chunk_size=chunk_size, fsync_period=None)
    writer.add_metadata('impact_damper_sim', {'scene': 'test: true\n'})
    for topic in TOPICS:
        writer.add_topic(topic, FLOAT64, {'depth': 10})
    for i in range(n):
        topic = TOPICS[i % len(TOPICS)]
        if late_after is not None and i >= late_after and i % 3 == 0:
            topic = '/late'
        assert writer.write(topic, FLOAT64, {'depth': 10}, _payload(i), T0 + i, T0 + i)
    writer.flush()
    crashed = path.read_bytes()
    writer.close()
    from mcap.reader import make_reader
    with open(path, 'rb') as f:
        chunks = sorted(make_reader(f).get_summary().chunk_indexes,
                        key=lambda c: c.chunk_start_offset)
    assert path.read_bytes().startswith(crashed)
    assert all(c.chunk_start_offset + c.chunk_length <= len(crashed) for c in chunks)
    return crashed, path, chunks


def _in_chunk(messages, chunk):
    return {m for m in messages if chunk.message_start_time <= m[1] <= chunk.message_end_time}


# the offset of a byte within a chunk record: opcode, length, then the chunk's fields
CHUNK_FIELDS = {'opcode': 0, 'record length': 1, 'message_start_time': 9,
                'message_end_time': 17, 'uncompressed_size': 25, 'uncompressed_crc': 33,
                'compression length': 37, 'records length': 41, 'records': 49}


# --------------------------------------------------------------------------- item 3

@pytest.mark.parametrize('which', ['first', 'middle', 'last'])
def test_crashed_log_with_a_bad_byte_in_one_chunk_keeps_every_other_chunk(tmp_path, which):
    """One byte flipped inside a chunk's records of a crashed log: recovery keeps every
    message of every other chunk, on its topic, with its payload (it kept 0 of 7,201 when
    the byte was in chunk 0: the channel records were only there)."""
    crashed, finished, chunks = _crashed_log(tmp_path)
    assert len(chunks) >= 10
    bad = chunks[{'first': 0, 'middle': len(chunks) // 2, 'last': -1}[which]]
    blob = bytearray(crashed)
    blob[bad.chunk_start_offset + CHUNK_FIELDS['records'] + 100] ^= 0x01
    src = tmp_path / 'damaged.mcap'
    src.write_bytes(bytes(blob))
    report = recover(src, tmp_path / 'out.mcap')
    everything = _messages(finished)
    lost = _in_chunk(everything, bad)
    assert len(everything) == 700 and 0 < len(lost) < 100
    assert report.messages == 700 - len(lost)
    assert _messages(tmp_path / 'out.mcap') == everything - lost
    assert report.skipped_messages == 0 and report.corrupt_chunks == 1
    assert report.corrupt_chunk_messages == len(lost)
    assert set(report.topics) == set(TOPICS) and not report.complete


def test_any_byte_of_a_chunks_framing_loses_that_chunk_at_most(tmp_path):
    """Each byte of chunk 0's opcode, length and header fields, and some of its records,
    flipped in turn (all bits): recovery keeps every message outside chunk 0 and never a
    message that was not written. A damaged length or opcode makes the reader look for the
    next intact chunk (it stopped there before, keeping nothing)."""
    crashed, finished, chunks = _crashed_log(tmp_path, n=300)
    everything = _messages(finished)
    first = chunks[0]
    outside = everything - _in_chunk(everything, first)
    offsets = list(range(CHUNK_FIELDS['records'] + 1)) + [CHUNK_FIELDS['records'] + 9,
                                                          first.chunk_length - 1]
    src, out = tmp_path / 'damaged.mcap', tmp_path / 'out.mcap'
    for offset in offsets:
        blob = bytearray(crashed)
        blob[first.chunk_start_offset + offset] ^= 0xFF
        src.write_bytes(bytes(blob))
        report = recover(src, out, overwrite=True)
        kept = _messages(out)
        assert outside <= kept <= everything, (offset, len(kept), len(outside))
        assert report.messages == len(kept) and report.skipped_messages == 0, offset


def test_a_topic_registered_late_survives_damage_to_the_chunk_after_it(tmp_path):
    """A topic added mid-run: its definitions are written outside chunks when it is
    registered, so the chunk that first holds its messages can be lost alone."""
    crashed, finished, chunks = _crashed_log(tmp_path, late_after=350)
    everything = _messages(finished)
    late = {m for m in everything if m[0] == '/late'}
    first_late = min(m[1] for m in late)
    index = next(k for k, c in enumerate(chunks) if c.message_end_time >= first_late)
    bad = chunks[index]
    blob = bytearray(crashed)
    blob[bad.chunk_start_offset + CHUNK_FIELDS['records'] + 50] ^= 0x01
    src = tmp_path / 'damaged.mcap'
    src.write_bytes(bytes(blob))
    report = recover(src, tmp_path / 'out.mcap')
    lost = _in_chunk(everything, bad)
    assert _messages(tmp_path / 'out.mcap') == everything - lost
    assert report.topics['/late'] == len(late - lost) > 0 and report.skipped_messages == 0


def test_study_recover_exits_non_zero_when_it_keeps_nothing(tmp_path, capsys):
    """All messages in one chunk, that chunk damaged; and a log cut before its first chunk:
    `study recover` exits 1 with one line saying why. An intact log with no messages is
    not a failure (exit 0)."""
    crashed, _, chunks = _crashed_log(tmp_path, n=10, chunk_size=1 << 20)
    assert len(chunks) == 1
    blob = bytearray(crashed)
    blob[chunks[0].chunk_start_offset + CHUNK_FIELDS['records'] + 30] ^= 0x01
    src, out = tmp_path / 'damaged.mcap', tmp_path / 'out.mcap'
    src.write_bytes(bytes(blob))
    assert study_main(['recover', str(src), str(out)]) == 1
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert len(err.splitlines()) == 1 and 'Traceback' not in err, err
    assert err.startswith('study: error: ') and 'no messages' in err and 'corrupt' in err, err
    assert 'recovered 0 messages' not in captured.out

    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(crashed[:chunks[0].chunk_start_offset])   # killed before the first chunk
    assert study_main(['recover', str(cut), str(out), '--overwrite']) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and 'no messages' in err, err

    empty = tmp_path / 'empty.mcap'
    Rosbag2McapWriter(empty).close()
    assert study_main(['recover', str(empty), str(out), '--overwrite']) == 0
    assert 'recovered 0 messages' in capsys.readouterr().out
    assert study_main(['recover', str(src), str(out), '--overwrite', '--json']) == 1
    assert json.loads(capsys.readouterr().out)['messages'] == 0


def test_definitions_are_outside_chunks_and_readers_still_read_finished_files(tmp_path):
    """Where the definitions are: a Schema and a Channel record for every topic before the
    first chunk (besides chunk 0's copies); mcap's reader and rosbags read the finished
    file whole."""
    from mcap.records import Channel, Chunk, Schema
    from mcap.stream_reader import StreamReader
    _, finished, _ = _crashed_log(tmp_path, n=100)
    outside, seen_chunk = [], False
    with open(finished, 'rb') as f:
        for record in StreamReader(f, emit_chunks=True).records:
            seen_chunk = seen_chunk or isinstance(record, Chunk)
            if isinstance(record, (Schema, Channel)) and not seen_chunk:
                outside.append(record)
    assert {r.topic for r in outside if isinstance(r, Channel)} == set(TOPICS)
    assert [r.name for r in outside if isinstance(r, Schema)] == [FLOAT64]
    assert len(_messages(finished)) == 100
    rosbags = pytest.importorskip('rosbags.rosbag2')
    reader = rosbags.Reader(finished)
    reader.open()
    try:
        assert reader.message_count == 100
        assert {c.topic for c in reader.connections} == set(TOPICS)
        assert sum(1 for _ in reader.messages()) == 100
    finally:
        reader.close()


# --------------------------------------------------------------------------- item 4

def _one_line(exc):
    text = str(exc)
    assert '\n' not in text and not text.startswith('[Errno') and 'Traceback' not in text
    return text


@pytest.mark.parametrize('overwrite', [False, True])
@pytest.mark.parametrize('second', [Rosbag2McapWriter, AsyncRecorder])
def test_a_second_writer_in_this_process_is_refused(tmp_path, overwrite, second):
    """Two writers, one file, one process (overwrite or not): the second is refused in one
    line naming the file and the holder, and the first log reads whole."""
    path = tmp_path / 'same.mcap'
    first = Rosbag2McapWriter(path)
    for i in range(50):
        first.write('/v', FLOAT64, None, _payload(i), T0 + i, T0 + i)
    first.flush()
    with pytest.raises(OSError) as caught:
        second(path, overwrite=overwrite)
    text = _one_line(caught.value)
    assert text.startswith(f'{path} is being written by ') and 'not writing it' in text, text
    assert f'process {os.getpid()}' in text, text
    assert not isinstance(caught.value, FileExistsError)
    for i in range(50, 100):
        first.write('/v', FLOAT64, None, _payload(i), T0 + i, T0 + i)
    first.close()
    assert first.finished and len(_messages(path)) == 100
    Rosbag2McapWriter(path, overwrite=True).close()   # the lock goes with the writer


_HOLDER = '''
import sys
from impact_damper_sim.recording import Rosbag2McapWriter
w = Rosbag2McapWriter(sys.argv[1])
for i in range(50):
    w.write('/v', 'std_msgs/msg/Float64', None, b'\\0\\1\\0\\0' + bytes(8), i, i)
w.flush()
print('ready', flush=True)
if sys.stdin.readline().strip() == 'close':
    w.close()
    print('closed', flush=True)
'''


def _holder(path):
    """Start a process writing ``path`` (50 messages flushed); it closes on 'close'."""
    (path.parent / 'holder.py').write_text(_HOLDER)
    env = dict(os.environ, PYTHONPATH=str(HERE.parent))
    child = subprocess.Popen([sys.executable, 'holder.py', path.name], cwd=path.parent,
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
    assert child.stdout.readline().strip() == 'ready'
    return child


def _close(child):
    """Let the holder close its log (a finished file) and exit."""
    try:
        child.stdin.write('close\n')
        child.stdin.flush()
        assert child.stdout.readline().strip() == 'closed'
    finally:
        child.stdin.close()
        child.wait(timeout=30)


@pytest.mark.parametrize('overwrite', [False, True])
def test_a_writer_in_another_process_is_named_and_its_log_kept(tmp_path, overwrite):
    path = tmp_path / 'same.mcap'
    child = _holder(path)
    try:
        with pytest.raises(OSError) as caught:
            AsyncRecorder(path, overwrite=overwrite, overwrite_option='record_overwrite:=true')
        text = _one_line(caught.value)
        assert f'is being written by process {child.pid} (' in text, text
        assert str(path) in text and f'holder.py {path.name})' in text, text
    finally:
        _close(child)
    assert len(_messages(path)) == 50


@pytest.mark.parametrize('overwrite', [False, True])
def test_study_record_names_the_writer_of_a_log_in_use(tmp_path, capsys, overwrite):
    """``study record --out`` a log another process is writing: one line naming that writer,
    with or without --overwrite (it said "exists; pass --overwrite", which then failed), and
    the other writer's log is kept whole."""
    path = tmp_path / 'same.mcap'
    child = _holder(path)
    try:
        rc = study_main(['record', 'sdof', '--duration', '0.05', '--out', str(path)]
                        + (['--overwrite'] if overwrite else []))
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2 and len(err) == 1, err
        assert err[0].startswith(f'study: error: {path} is being written by process '
                                 f'{child.pid} (') and err[0].endswith('; not writing it'), err
        assert 'pass --overwrite' not in err[0]
    finally:
        _close(child)
    assert len(_messages(path)) == 50


def test_a_killed_holder_leaves_no_stale_lock(tmp_path):
    """SIGKILL the holder: its lock goes with it (kernel-held), so the crashed log can be
    replaced, and no lock file is left beside it."""
    path = tmp_path / 'same.mcap'
    child = _holder(path)
    child.send_signal(signal.SIGKILL)
    child.wait(timeout=30)
    assert recover(path, tmp_path / 'rec.mcap').messages == 50
    with Rosbag2McapWriter(path, overwrite=True) as writer:
        writer.write('/v', FLOAT64, None, _payload(1), T0, T0)
    assert len(_messages(path)) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ['holder.py', 'rec.mcap', 'same.mcap']


# --------------------------------------------------------------------------- writer contract

@pytest.mark.parametrize('make', [Rosbag2McapWriter, AsyncRecorder])
@pytest.mark.parametrize('overwrite', [False, True])
def test_opening_errors_are_one_line_oserrors(tmp_path, make, overwrite):
    missing = tmp_path / 'no' / 'such' / 'dir' / 'x.mcap'
    with pytest.raises(FileNotFoundError) as caught:
        make(missing, overwrite=overwrite)
    text = _one_line(caught.value)
    assert text.startswith(f'cannot create {missing}: ') and 'No such file' in text, text
    assert caught.value.errno == errno.ENOENT
    a_dir = tmp_path / 'adir.mcap'
    a_dir.mkdir()
    with pytest.raises(IsADirectoryError) as caught:
        make(a_dir, overwrite=overwrite)
    assert _one_line(caught.value) == f'cannot create {a_dir}: Is a directory'


def _read_only_dir(tmp_path):
    """A read-only tmpfs in a private mount namespace; skip where one cannot be made."""
    ro = tmp_path / 'ro'
    ro.mkdir()
    if not shutil.which('unshare'):
        pytest.skip('no unshare(1) to mount a read-only file system')
    probe = subprocess.run(['unshare', '-m', 'sh', '-c',
                            f'mount -t tmpfs -o ro,size=64k tmpfs {ro} && echo ok'],
                           capture_output=True, text=True)
    if probe.stdout.strip() != 'ok':
        pytest.skip(f'cannot mount a read-only tmpfs here: {probe.stderr.strip()}')
    return ro


def test_a_read_only_file_system_is_one_line(tmp_path):
    ro = _read_only_dir(tmp_path)
    code = ('import sys\nfrom impact_damper_sim.recording import Rosbag2McapWriter\n'
            'try:\n    Rosbag2McapWriter(sys.argv[1])\n'
            'except OSError as exc:\n    print(type(exc).__mro__[1].__name__, exc.errno)\n'
            '    print(exc)\n')
    env = dict(os.environ, PYTHONPATH=str(HERE.parent))
    proc = subprocess.run(['unshare', '-m', 'sh', '-c',
                           f'mount -t tmpfs -o ro,size=64k tmpfs {ro} && '
                           f'exec "{sys.executable}" -c \'{code}\' {ro}/x.mcap'],
                          capture_output=True, text=True, env=env, timeout=60)
    lines = proc.stdout.splitlines()
    assert len(lines) == 2 and lines[0].endswith(f' {errno.EROFS}'), (proc.stdout, proc.stderr)
    assert lines[1] == f'cannot create {ro}/x.mcap: Read-only file system'


@pytest.mark.parametrize('how', ['file deleted', 'directory removed', 'file moved'])
@pytest.mark.parametrize('make', [Rosbag2McapWriter, AsyncRecorder])
def test_a_log_that_vanishes_while_written_is_an_error(tmp_path, how, make):
    """The file deleted, its directory removed, or the file moved away while being written:
    after close() ``error`` names what happened and ``finished`` is False (the writes all
    succeeded, so only the writer can tell)."""
    folder = tmp_path / 'run'
    folder.mkdir()
    path = folder / 'a.mcap'
    errors = []
    writer = make(path, on_error=errors.append)
    writer.write('/v', FLOAT64, None, _payload(0), T0, T0)
    if how == 'file deleted':
        path.unlink()
    elif how == 'directory removed':
        shutil.rmtree(folder)
    else:
        path.rename(tmp_path / 'elsewhere.mcap')
    writer.write('/v', FLOAT64, None, _payload(1), T0 + 1, T0 + 1)
    writer.close()
    assert isinstance(writer.error, OSError) and writer.error.errno == errno.ENOENT
    text = _one_line(writer.error)
    word = 'moved' if how == 'file moved' else 'deleted'
    assert text.startswith(f'{path} was {word} while being written'), text
    assert errors == [writer.error]
    stats = writer.stats()
    assert writer.finished is False and stats['finished'] is False and stats['error']
    if how == 'file moved':   # a moved file still took the data, and the error says where
        assert f'(the file is now {tmp_path / "elsewhere.mcap"})' in text, text
        assert len(_messages(tmp_path / 'elsewhere.mcap')) == 2


def test_a_chdir_is_not_a_move(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    writer = Rosbag2McapWriter('rel.mcap')
    writer.write('/v', FLOAT64, None, _payload(0), T0, T0)
    monkeypatch.chdir('/')
    writer.close()
    assert writer.finished and writer.error is None


def test_a_deleted_log_is_reported_when_it_happens(tmp_path):
    """Deletion is seen at the next fsync tick, not only at close (on_error runs then, so a
    node can log it when it happens); later messages are dropped, not written to nowhere."""
    clock = [0.0]
    errors = []
    path = tmp_path / 'a.mcap'
    writer = Rosbag2McapWriter(path, clock=lambda: clock[0], on_error=errors.append,
                               flush_period=0.5, fsync_period=1.0)
    assert writer.write('/v', FLOAT64, None, _payload(0), T0, T0)
    path.unlink()
    clock[0] += 1.0
    writer.poll()
    assert len(errors) == 1 and 'was deleted while being written' in str(errors[0])
    assert writer.write('/v', FLOAT64, None, _payload(1), T0 + 1, T0 + 1) is False
    writer.close()
    assert errors == [writer.error] and not writer.finished


@pytest.mark.skipif(not os.path.exists('/dev/full'), reason='needs /dev/full')
@pytest.mark.parametrize('make', [Rosbag2McapWriter, AsyncRecorder])
def test_disk_full_is_not_finished(tmp_path, make):
    link = tmp_path / 'full.mcap'
    link.symlink_to('/dev/full')
    writer = make(link, overwrite=True)
    writer.write('/v', FLOAT64, None, _payload(0), T0, T0)
    writer.close()
    assert writer.error is not None and writer.error.errno == errno.ENOSPC
    assert writer.finished is False and writer.stats()['finished'] is False


@pytest.mark.parametrize('make', [Rosbag2McapWriter, AsyncRecorder])
def test_a_finished_log_says_so(tmp_path, make):
    path = tmp_path / 'ok.mcap'
    writer = make(path)
    writer.write('/v', FLOAT64, None, _payload(0), T0, T0)
    assert writer.finished is False and writer.stats()['finished'] is False
    writer.close()
    assert writer.error is None and writer.finished is True
    assert writer.stats()['finished'] is True and len(_messages(path)) == 1


def test_one_line_errors_survive_pickling(tmp_path):
    """A dataset worker's error crosses a process boundary: the one-line text stays."""
    import pickle
    with pytest.raises(OSError) as caught:
        Rosbag2McapWriter(tmp_path / 'no' / 'x.mcap')
    again = pickle.loads(pickle.dumps(caught.value))
    assert str(again) == str(caught.value) and type(again) is type(caught.value)
    assert again.errno == errno.ENOENT
