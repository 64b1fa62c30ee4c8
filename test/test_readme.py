"""The README and the docs/ pages stay true: generated tables equal their sources, and every
example runs as written."""
import re
from pathlib import Path

import pytest

from impact_damper_sim.scene.keytable import markdown_table
from impact_damper_sim.scene.spec import SCHEMA

README = Path(__file__).resolve().parents[1] / 'README.md'


DOCS = sorted((README.parent / 'docs').glob('*.md'))


def region(name):
    """The text between ``<!-- name:start -->`` and ``<!-- name:end -->``, in the README or
    a docs/ page (exactly one of them)."""
    found = [p.read_text() for p in [README, *DOCS]
             if f'<!-- {name}:start -->' in p.read_text()]
    assert len(found) == 1, f'region {name!r} in {len(found)} pages'
    return found[0].split(f'<!-- {name}:start -->\n')[1].split(f'<!-- {name}:end -->')[0]


def test_key_table_is_the_schema():
    # regenerate with: .venv/bin/impact_damper_study keys --markdown
    text = region('scene-keys')
    table = markdown_table(SCHEMA)
    assert text.endswith('\n' + table), 'README key table differs from the schema'
    assert text.count('| Key | Type | Default | Range | Description |') == 1


def test_simulation_api_example_runs():
    code = re.search(r'```python\n(.*?)```', region('simulation-api'), flags=re.S).group(1)
    namespace = {}
    exec(compile(code, 'README.md', 'exec'), namespace)
    sim = namespace['sim']
    assert sim.t == 2.0 and namespace['acc'].shape == (10000, 1)



def test_node_parameter_table_is_the_declared_one():
    pytest = __import__('pytest')
    pytest.importorskip('rclpy')
    from impact_damper_sim.ros.parameters import parameters_markdown
    assert region('node-params').strip() == parameters_markdown()


def test_params_file_holds_every_parameter_default():
    pytest = __import__('pytest')
    pytest.importorskip('rclpy')
    import yaml
    from rclpy.parameter import Parameter

    from impact_damper_sim.ros.parameters import PARAMETERS
    params = yaml.safe_load((README.parent / 'config' / 'vibration_node.yaml').read_text())
    params = params['/**']['ros__parameters']
    for name, (default, *_rest) in PARAMETERS.items():
        if isinstance(default, Parameter.Type):
            assert name not in params   # an empty string array cannot be written in YAML
        else:
            assert params[name] == default, name


def test_topic_table_names_every_topic():
    pytest = __import__('pytest')
    pytest.importorskip('rclpy')
    from impact_damper_sim.ros import interface as itf
    text = README.read_text()
    for topic in (itf.IMPACTS, itf.IMPACTOR_STATE, itf.ROTOR_SPEED, itf.ROTOR_JOINT_STATES,
                  itf.ROTOR_TACH, itf.ROTOR_KEYPHASOR, itf.SPEED_COMMAND,
                  itf.UNBALANCE_COMMAND, itf.FAULT_COMMAND, itf.CLOCK, itf.DIAGNOSTICS,
                  'accel/<accelerometer>',
                  itf.accel_truth_topic('<accelerometer>')):
        assert f'| `{topic}`' in text, topic


def test_python_command_example_reaches_the_node(ros_context, tmp_path):
    """The README's commander, run as written in its own process, steers a running node."""
    pytest = __import__('pytest')
    pytest.importorskip('rclpy')
    import os
    import subprocess
    import sys
    import time

    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from impact_damper_sim.ros.vibration_node import VibrationNode
    code = re.search(r'```python\n(.*?)```', region('command-example'), flags=re.S).group(1)
    script = tmp_path / 'commander.py'
    script.write_text(code)
    node = VibrationNode(context=ros_context, start_stepping=False, parameter_overrides=[
        Parameter('scene', value='hpotp'), Parameter('overrides', value=['impactors=[]'])])
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    env = dict(os.environ, ROS_DOMAIN_ID=str(ros_context.get_domain_id()))
    try:
        proc = subprocess.Popen([sys.executable, str(script)], env=env)
        end = time.monotonic() + 60.0
        while proc.poll() is None and time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
        for _ in range(20):
            ex.spin_once(timeout_sec=0.05)
        assert proc.wait(timeout=5) == 0
        assert node.live.profile.target == 600.0
    finally:
        node.destroy_node()


def _run_examples():
    """Every README command that starts a node: sh-block lines and command-table cells."""
    text = ''.join(p.read_text() for p in [README, *DOCS])
    lines = [ln for block in re.findall(r'```sh\n(.*?)```', text, flags=re.S)
             for ln in block.splitlines()]
    lines += re.findall(r'\| `(make run[^`]*)` \|', text)
    found = []
    for line in lines:
        command = line.split('  #')[0].strip().rstrip('&').strip()
        if re.match(r'(make run|\.venv/bin/(vibration_node|impact_damper_monitor))\b', command):
            found.append(command)
    return sorted(set(found))


def test_readme_names_node_examples():
    commands = _run_examples()
    assert "make run SCENE=rbs NODE_ARGS='-p real_time_factor:=0.5'" in commands
    assert any('__ns:=/rbs' in c for c in commands)


@pytest.mark.parametrize('command', _run_examples())
def test_readme_node_example_runs_as_written(command):
    """Each example starts (the node logs its start-up line, or the monitor stays up) and
    stops on Ctrl-C; a start-up error would print one line and exit 2."""
    pytest.importorskip('rclpy')
    import os
    import signal
    import subprocess
    import time

    from conftest import next_domain_id
    env = dict(os.environ, ROS_DOMAIN_ID=str(next_domain_id()))
    proc = subprocess.Popen(['bash', '-c', f'exec {command}'], cwd=README.parent, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True)
    out = []
    reader = __import__('threading').Thread(target=lambda: out.extend(proc.stdout),
                                            daemon=True)
    reader.start()
    try:
        started = 'monitor' in command   # the monitor has nothing to wait for
        end = time.monotonic() + (5.0 if started else 180.0)
        while time.monotonic() < end and proc.poll() is None:
            if not started and 'accelerometers at' in ''.join(out):
                break
            time.sleep(0.2)
        time.sleep(1.0)
        text = ''.join(out)
        assert proc.poll() is None, f'{command} exited {proc.returncode}:\n{text}'
        assert 'Traceback' not in text, text
        if not started:
            assert 'accelerometers at' in text, text
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(timeout=30)
        if not command.startswith('make'):
            assert proc.returncode == 0, ''.join(out)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def test_command_table_names_every_study_command_and_option():
    """Each `study` sub-command has a row naming its options (shared ones: the study-options
    line under the table)."""
    import argparse

    from impact_damper_sim.cli.study import _parser
    text = README.read_text()
    shared = region('study-options')
    sub = next(a for a in _parser()._actions if isinstance(a, argparse._SubParsersAction))
    for name, parser in sub.choices.items():
        rows = [ln for ln in text.splitlines()
                if ln.startswith(f'| `.venv/bin/impact_damper_study {name} ')
                or ln.startswith(f'| `.venv/bin/impact_damper_study {name}`')]
        assert len(rows) == 1, name
        for action in parser._actions:
            for option in (o for o in action.option_strings
                           if o.startswith('--') and o != '--help'):
                assert option in rows[0] or (option in shared and '[study options]' in rows[0]), \
                    (name, option)


def test_docs_links_resolve():
    """Relative links of the README and the docs pages point at files of this repository."""
    for page in [README, *DOCS]:
        for target in re.findall(r'\]\(([^)#]+)(?:#[^)]*)?\)', page.read_text()):
            if '://' in target:
                continue
            assert (page.parent / target).exists(), (page.name, target)
    assert '../shared/' not in README.read_text()


def _cli_lines():
    """README sh-block lines that talk to a running node or write and read a log: the
    ``ros2 topic pub`` / ``param set`` / ``service call`` and ``study record``/``report`` ones."""
    lines = [ln.split('  #')[0].strip()
             for block in re.findall(r'```sh\n(.*?)```', README.read_text(), flags=re.S)
             for ln in block.splitlines()]
    return [ln for ln in lines
            if re.match(r'ros2 (topic pub|param set|service call) |'
                        r'\.venv/bin/impact_damper_study (record|report) ', ln)]


def test_readme_cli_commands_run_as_written(tmp_path):
    """Steering and recording, as the README's first screens type them, against a live node
    (default scene) on a domain of its own: each exits 0, the recording lands in the
    directory the node runs in, and ``study report`` reads the log ``study record`` wrote."""
    pytest.importorskip('rclpy')
    import os
    import signal
    import subprocess
    import sys
    import threading
    import time

    from conftest import next_domain_id
    bindir = os.path.dirname(sys.executable)
    if not os.path.exists(os.path.join(bindir, 'ros2')):
        pytest.skip('the ROS 2 command line is not installed (make ros2cli)')
    lines = _cli_lines()
    assert sum(ln.startswith('ros2 ') for ln in lines) >= 5, lines
    (tmp_path / '.venv').symlink_to(README.parent / '.venv')   # `.venv/bin/...` as written
    env = dict(os.environ, ROS_DOMAIN_ID=str(next_domain_id()),
               AMENT_PREFIX_PATH=os.environ.get('AMENT_PREFIX_PATH', os.path.dirname(bindir)),
               PATH=bindir + os.pathsep + os.environ['PATH'])
    node = subprocess.Popen([os.path.join(bindir, 'vibration_node')], cwd=tmp_path, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True)
    out = []
    threading.Thread(target=lambda: out.extend(node.stdout), daemon=True).start()
    try:
        end = time.monotonic() + 180.0
        while time.monotonic() < end and node.poll() is None \
                and 'accelerometers at' not in ''.join(out):
            time.sleep(0.2)
        assert 'accelerometers at' in ''.join(out), ''.join(out)
        for _ in range(60):   # as a user would: the CLI's graph has to know the node first
            listed = subprocess.run(['ros2', 'node', 'list'], env=env, capture_output=True,
                                    text=True, timeout=60)
            if '/vibration_node' in listed.stdout.split():
                break
            time.sleep(1.0)
        for line in lines:
            done = subprocess.run(['bash', '-c', line], cwd=tmp_path, env=env, timeout=120,
                                  capture_output=True, text=True)
            assert done.returncode == 0, (line, done.stdout, done.stderr)
        assert len(list(tmp_path.glob('hpotp_*.mcap'))) == 1, sorted(tmp_path.iterdir())
        assert 'accelerations in g' in done.stdout      # the last line: study report
        time.sleep(1.0)
        text = ''.join(out)
        for said in ('rotor/speed_command 600 accepted', 'rotor/unbalance_command 10 accepted',
                     'recording to hpotp_', 'recorded '):
            assert said in text, (said, text)
    finally:
        if node.poll() is None:
            os.killpg(node.pid, signal.SIGINT)
            try:
                node.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(node.pid, signal.SIGKILL)
                node.wait()
        subprocess.run([os.path.join(bindir, 'ros2'), 'daemon', 'stop'], env=env,
                       capture_output=True, timeout=60)
