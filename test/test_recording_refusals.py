"""A recording that cannot start says why in one line, names what the user can set, and
leaves no file behind."""
import errno
import os
import subprocess
import sys
from pathlib import Path

import pytest

from impact_damper_sim.recording import AsyncRecorder, Rosbag2McapWriter
from impact_damper_sim.recording.definitions import AmentIndexError, DefinitionNotFoundError

ROOT = Path(__file__).resolve().parents[1]


def test_recorder_without_ament_prefix_path_refuses_before_creating_the_file(
        tmp_path, monkeypatch):
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    path = tmp_path / 'run.mcap'
    with pytest.raises(AmentIndexError) as caught:
        AsyncRecorder(path)
    exc = caught.value
    # an OSError: what the node's start_recording turns into a one-line parameter error
    assert isinstance(exc, OSError) and isinstance(exc, DefinitionNotFoundError)
    text = str(exc)
    assert '\n' not in text and 'AMENT_PREFIX_PATH' in text and str(path) in text, text
    if (Path(sys.prefix) / 'share' / 'std_msgs' / 'msg').is_dir():
        assert f'AMENT_PREFIX_PATH={sys.prefix}' in text, text   # the value to set
    assert not path.exists()


def test_recorder_with_a_prefix_without_messages_refuses(tmp_path, monkeypatch):
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path))
    path = tmp_path / 'run.mcap'
    with pytest.raises(OSError, match='no message definitions of builtin_interfaces'):
        AsyncRecorder(path)
    assert not path.exists()


def test_existing_file_message_names_the_option_the_caller_passes(tmp_path):
    pytest.importorskip('ament_index_python')
    if not os.environ.get('AMENT_PREFIX_PATH'):
        pytest.skip('AMENT_PREFIX_PATH is not set (make test sets it)')
    path = tmp_path / 'run.mcap'
    path.write_bytes(b'keep me')
    with pytest.raises(FileExistsError) as default:
        Rosbag2McapWriter(path)
    assert str(default.value) == (f'{path} exists; not overwriting it (set overwrite=True to '
                                  f'replace it)')
    assert default.value.errno == errno.EEXIST and default.value.filename == str(path)
    with pytest.raises(FileExistsError) as node:
        AsyncRecorder(path, overwrite_option='record_overwrite:=true')
    text = str(node.value)
    assert 'record_overwrite:=true' in text and 'overwrite=True' not in text, text
    assert not text.startswith('[Errno') and '\n' not in text
    assert path.read_bytes() == b'keep me'


def _node_env(tmp_path, **changes):
    from conftest import next_domain_id
    env = dict(os.environ, ROS_DOMAIN_ID=str(next_domain_id()),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', ROS_LOG_DIR=str(tmp_path / 'log'))
    for key, value in changes.items():
        if value is None:
            env.pop(key, None)
        else:
            env[key] = value
    return env


def _vibration_node():
    exe = Path(sys.prefix) / 'bin' / 'vibration_node'
    if not exe.is_file():
        pytest.skip(f'no console script {exe}: run `make`')
    return str(exe)


def test_node_records_without_ament_prefix_path_one_line_exit_2(tmp_path):
    """docs/node.md's promise: one line on stderr, exit status 2, and no partial MCAP."""
    pytest.importorskip('rclpy')
    out = tmp_path / 'F.mcap'
    proc = subprocess.run(
        [_vibration_node(), '--ros-args', '-p', 'scene:=sdof', '-p', f'record:={out}'],
        cwd=tmp_path, env=_node_env(tmp_path, AMENT_PREFIX_PATH=None),
        capture_output=True, text=True, timeout=180)
    err = proc.stderr.strip()
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert 'Traceback' not in proc.stderr and len(err.splitlines()) == 1, proc.stderr
    assert err.startswith("vibration_node: parameter 'record': ") and \
        'AMENT_PREFIX_PATH' in err, err
    assert not out.exists(), 'a refused recording left a file behind'


def test_node_refusing_an_existing_record_file_names_record_overwrite(tmp_path):
    pytest.importorskip('rclpy')
    out = tmp_path / 'F.mcap'
    out.write_bytes(b'keep me')
    proc = subprocess.run(
        [_vibration_node(), '--ros-args', '-p', 'scene:=sdof', '-p', f'record:={out}'],
        cwd=tmp_path, env=_node_env(tmp_path), capture_output=True, text=True, timeout=180)
    err = proc.stderr.strip()
    assert proc.returncode == 2 and len(err.splitlines()) == 1, proc.stderr
    assert out.read_bytes() == b'keep me'
    assert 'record_overwrite' in err and 'overwrite=True' not in err, err
