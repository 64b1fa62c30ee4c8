"""``plant_host`` (issue 39 item 3): several machines in one process, one executor.

Each machine is its own node in its own namespace: its topics are namespaced, its
``/diagnostics`` status carries its fully qualified name, its seed is its own (the streams of
two machines of one scene differ sample for sample), and Ctrl-C ends the process with 0."""
import os
import signal
import subprocess
import sys
import time

import pytest

from impact_damper_sim.ros.plant_host import machine_specs, parse_machine, parse_share
from impact_damper_sim.scene.schema import SceneError


# --------------------------------------------------------------------- the machine list
def test_machines_are_seeded_apart_and_only_the_first_publishes_the_clock():
    specs, notes = machine_specs(['pump1:hpotp', 'pump2:rbs', '/plant/pump3:sdof'], seed=40)
    assert [s.namespace for s in specs] == ['pump1', 'pump2', 'plant/pump3']
    assert [s.scene for s in specs] == ['hpotp', 'rbs', 'sdof']
    assert [s.parameters['noise_seed'] for s in specs] == [40, 41, 42]
    assert [s.parameters['publish_clock'] for s in specs] == [True, False, False]
    assert notes == []
    everyone, _ = machine_specs(['a:sdof', 'b:sdof'], clock='all')
    assert all('publish_clock' not in s.parameters for s in everyone)   # the node's default
    nobody, _ = machine_specs(['a:sdof', 'b:sdof'], clock='none')
    assert [s.parameters['publish_clock'] for s in nobody] == [False, False]


def test_a_plant_file_comes_first_with_its_seeds_then_the_command_line_machines():
    specs, _ = machine_specs(['spare:sdof'], plant='mixed')
    assert [s.namespace for s in specs] == ['hpotp1', 'rbs1', 'rbs_kcc1', 'beam1', 'spare']
    # the plant's seed 200 + index, continued for the command line's machine
    assert [s.parameters['noise_seed'] for s in specs] == [200, 201, 202, 203, 204]
    assert specs[0].parameters['overrides'] == ['rotor.multiplier=1.5']
    reseeded, _ = machine_specs(['spare:sdof'], plant='mixed', seed=7)
    assert [s.parameters['noise_seed'] for s in reseeded] == [7, 8, 9, 10, 11]


@pytest.mark.parametrize('machines, message', [
    (['pump1hpotp'], 'not namespace:scene'),
    (['pump1:'], 'not namespace:scene'),
    (['pump1:hpotp', '/pump1:rbs'], "namespace 'pump1' is also machine 0's"),
    ([], 'no machines'),
])
def test_a_bad_machine_list_is_refused_naming_the_entry(machines, message):
    with pytest.raises(SceneError, match=message):
        machine_specs(machines)


def test_five_shares_of_a_plant_are_disjoint_and_together_the_whole_plant():
    """``--share i/5`` over i = 0..4: each machine in exactly one share (index i mod 5),
    with what it has in the whole plant: namespace, seed, parameters, and /clock only from
    machine 0's share."""
    whole, _ = machine_specs(plant='ten_hpotp')
    assert len(whole) == 10
    assert len({s.parameters['noise_seed'] for s in whole}) == 10   # the seeds do differ
    shares = [machine_specs(plant='ten_hpotp', share=(i, 5))[0] for i in range(5)]
    for i, share in enumerate(shares):
        assert [s.namespace for s in share] == [whole[i].namespace, whole[i + 5].namespace]
    hosted = [s for share in shares for s in share]
    names = [s.namespace for s in hosted]
    assert len(names) == len(set(names)) == 10
    by_name = {s.namespace: s.parameters for s in hosted}
    assert by_name == {s.namespace: s.parameters for s in whole}
    assert [s.namespace for s in shares[0] if s.parameters['publish_clock']] == \
        [whole[0].namespace]
    assert not any(s.parameters['publish_clock'] for share in shares[1:] for s in share)
    # the command line's machines are counted after the plant's, seeded as in the whole
    extra, _ = machine_specs(['spare:sdof'], plant='ten_hpotp', seed=50, share=(0, 5))
    assert [(s.namespace, s.parameters['noise_seed']) for s in extra] == [
        ('pump01', 50), ('pump06', 55), ('spare', 60)]


@pytest.mark.parametrize('share, message', [
    ((0, 0), r'--share 0/0: give I/K, integers with K >= 1 and 0 <= I < K'),
    ((5, 5), r'--share 5/5: give I/K, integers with K >= 1 and 0 <= I < K'),
    ((-1, 5), r'--share -1/5: give I/K'),
    ((10, 12), r'--share 10/12: no machine of the 10 has an index 10 modulo 12; give I/K '
               r'with 0 <= I < min\(K, 10\)'),
])
def test_a_bad_or_empty_share_is_refused_naming_the_option(share, message):
    with pytest.raises(SceneError, match=message):
        machine_specs(plant='ten_hpotp', share=share)


@pytest.mark.parametrize('text', ['0/0', '3', 'a/5', '1/2/3', '1.0/2'])
def test_share_text_that_is_not_i_over_k_is_refused_naming_the_option(text):
    with pytest.raises(SceneError, match=rf'^--share {text}: give I/K'):
        parse_share(text)
    assert parse_share(' 2/5') == (2, 5)


def test_stagger_overrides_the_plant_files_and_a_bad_one_is_refused_naming_the_option():
    """--stagger S (the launch's stagger:=S reaches every host so): machine i's schedule runs
    its rotor up at i x S, the whole plant's index, in every share."""
    import yaml
    specs, _ = machine_specs(plant='ten_hpotp', stagger=2.0, share=(1, 5))
    assert [s.namespace for s in specs] == ['pump02', 'pump07']
    for spec, index in zip(specs, (1, 6)):
        with open(spec.parameters['schedule']) as f:
            entries = yaml.safe_load(f)['schedule']
        assert entries[-1] == {'at': f'{2.0 * index!r} s', 'speed': '2400.0 rad/s'}, entries
    with pytest.raises(SceneError, match=r'^--stagger -1: give seconds from 0 to 60 '):
        machine_specs(plant='ten_hpotp', stagger=-1.0)


def test_parse_machine_strips_the_leading_slash():
    assert parse_machine('/a/b:rbs_kcc') == ('a/b', 'rbs_kcc')


# --------------------------------------------------------------------- the process
def _wait(until, timeout):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if until():
            return True
        time.sleep(0.05)
    return False


@pytest.mark.ros
def test_two_machines_in_one_process_are_told_apart_and_ctrl_c_exits_0(ros_context):
    """Two sdof machines (noise on, seeds 0 and 1): each publishes its own namespaced batch
    topic, /diagnostics holds two status names and two hardware_ids, the batches of one sim
    instant differ between the machines (their seeds), and SIGINT ends the process with 0."""
    rclpy = pytest.importorskip('rclpy')
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import PointCloud2

    tag = f'ph{os.getpid()}'
    machines = [f'{tag}_a', f'{tag}_b']
    env = dict(os.environ, ROS_DOMAIN_ID=str(ros_context.get_domain_id()))
    proc = subprocess.Popen(
        [sys.executable, '-m', 'impact_damper_sim.ros.plant_host',
         '--machines', *(f'{m}:sdof' for m in machines),
         '--ros-args', '-p', 'noise_std:=0.5'],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True)
    node = rclpy.create_node('plant_host_test', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    batches = {m: {} for m in machines}   # machine -> {stamp (ns): data bytes}
    status = {}                           # status name -> hardware_id

    def on_batch(machine):
        def take(msg):
            stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            batches[machine][stamp] = bytes(msg.data)
        return take

    def on_diagnostics(msg):
        for s in msg.status:
            if s.name.endswith('vibration_node: simulation'):
                status[s.name] = s.hardware_id

    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    for m in machines:
        node.create_subscription(PointCloud2, f'/{m}/accel/sdof_primary/batch',
                                 on_batch(m), qos)
    node.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, qos)

    def common():
        return sorted(set(batches[machines[0]]) & set(batches[machines[1]]))

    def spin_until(until, timeout):
        return _wait(lambda: (executor.spin_once(timeout_sec=0.05), until())[1], timeout)

    try:
        # a cold kernel cache compiles first (tens of s on a busy 2-core machine)
        done = spin_until(lambda: len(common()) >= 20 and len(status) >= 2, 120)
        assert proc.poll() is None, proc.communicate()[1]
        assert done, (f'batches {[len(b) for b in batches.values()]}, common '
                      f'{len(common())}, statuses {status}')
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        executor.shutdown()
        node.destroy_node()
    assert proc.returncode == 0, err
    assert 'Traceback' not in err, err
    assert status == {f'/{m}/vibration_node: simulation': f'{m}/sdof' for m in machines}
    same = [s for s in common() if batches[machines[0]][s] == batches[machines[1]][s]]
    assert not same, f'{len(same)} of {len(common())} batches of one instant are equal'
    assert all(len(batches[machines[0]][s]) == len(batches[machines[1]][s])
               for s in common())   # the same layout: only the values differ


@pytest.mark.ros
def test_an_empty_share_exits_2_with_one_line_naming_the_option():
    pytest.importorskip('rclpy')
    done = subprocess.run(
        [sys.executable, '-m', 'impact_damper_sim.ros.plant_host',
         '--machines', 'a:sdof', 'b:sdof', '--share', '2/3'],
        capture_output=True, text=True, timeout=180,
        env=dict(os.environ, ROS_DOMAIN_ID='67'))
    assert done.returncode == 2, done.stderr
    assert done.stderr.splitlines() == [
        'plant_host: --share 2/3: no machine of the 2 has an index 2 modulo 3; give I/K '
        'with 0 <= I < min(K, 2)'], done.stderr


@pytest.mark.ros
def test_a_machine_that_cannot_be_built_exits_2_naming_it():
    pytest.importorskip('rclpy')
    done = subprocess.run(
        [sys.executable, '-m', 'impact_damper_sim.ros.plant_host',
         '--machines', 'good:sdof', 'bad:no_such_scene'],
        capture_output=True, text=True, timeout=180,
        env=dict(os.environ, ROS_DOMAIN_ID='67'))
    assert done.returncode == 2, done.stderr
    lines = [ln for ln in done.stderr.splitlines() if ln.startswith('plant_host:')]
    assert len(lines) == 1 and 'machine 1 (bad:no_such_scene)' in lines[0], done.stderr
    assert 'Traceback' not in done.stderr, done.stderr
