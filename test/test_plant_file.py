"""Plant files (issue 39 item 5): a valid file maps each machine to its node's parameters, and
every problem is refused at load, all at once, each line naming its key and what it accepts.
No ROS: the loader is in ``scene/``."""
from pathlib import Path

import pytest
import yaml

from impact_damper_sim.scene.plant import (
    SEED_MAX,
    STAGGER_MAX,
    PlantError,
    load_plant,
    plant_files,
    resolve_plant,
)

ROOT = Path(__file__).resolve().parents[1]


def _plant(tmp_path, text, name='plant.yaml'):
    path = tmp_path / name
    path.write_text(text, encoding='utf-8')
    return path


def _errors(tmp_path, text):
    with pytest.raises(PlantError) as caught:
        load_plant(_plant(tmp_path, text))
    return list(caught.value.errors)


def test_a_valid_plant_gives_each_machine_its_node_parameters(tmp_path):
    plant = load_plant(_plant(tmp_path, """
plant: pumps_a
seed: 100
record: per_machine
record_dir: logs
machines:
  - namespace: pump1
    scene: hpotp
    unbalance: 1.5
    preset: iepe_10mv_500g
    noise_std: 0.01 g
    hardware_id: SN-0001
    faults:
      - {kind: gain, accelerometer: hpotp_casing_bottom, gain: 3, onset: 2 s}
  - {namespace: plant_b/pump2, scene: rbs, dampers: false}
  - {namespace: beam, scene: cantilever, seed: 7}
"""))
    assert plant.name == 'pumps_a' and plant.record == 'per_machine'
    assert plant.namespaces == ['pump1', 'plant_b/pump2', 'beam']
    params = plant.node_parameters(schedule_dir=tmp_path / 'schedules')
    p1 = params['pump1']
    assert p1['scene'] == 'hpotp' and p1['noise_seed'] == 100
    assert p1['noise_std'] == pytest.approx(0.01 * 9.80665)   # engineering units, SI out
    assert p1['overrides'] == ['rotor.multiplier=1.5', 'channel=iepe_10mv_500g']
    assert p1['hardware_id'] == 'SN-0001' and p1['dampers_enabled'] is True
    assert p1['record'] == str(Path('logs') / 'pump1.mcap') and p1['record_overwrite'] is False
    # the faults become the node's schedule: one entry each, in order, units as written
    schedule = yaml.safe_load(Path(p1['schedule']).read_text())['schedule']
    assert schedule == [{'at': '0 s', 'fault': {'kind': 'gain',
                                                'accelerometer': 'hpotp_casing_bottom',
                                                'gain': 3, 'onset': '2 s'}}]
    p2 = params['plant_b/pump2']
    assert p2['noise_seed'] == 101 and p2['dampers_enabled'] is False
    assert 'overrides' not in p2 and 'schedule' not in p2 and 'hardware_id' not in p2
    assert p2['record'] == str(Path('logs') / 'plant_b.pump2.mcap')   # '.' is in no ROS name
    assert params['beam']['noise_seed'] == 7
    labels = plant.labels()['machines']
    assert labels[0] == {'machine': 'pump1', 'scene': 'hpotp', 'seed': 100, 'unbalance': 1.5,
                         'preset': 'iepe_10mv_500g', 'hardware_id': 'SN-0001',
                         'faults': [{'kind': 'gain', 'accelerometer': 'hpotp_casing_bottom',
                                     'gain': 3, 'onset': '2 s'}]}
    # the scene's own preset when the machine gives none; the default hardware_id
    assert labels[1]['preset'] == 'iepe_100mv_50g'
    assert labels[1]['hardware_id'] == 'plant_b/pump2/rbs'


def test_every_machine_gets_its_own_seed(tmp_path):
    """Machine i gets seed + i unless it gives its own; two equal seeds are refused, since
    the seed is what makes two machines of one scene stream different signals."""
    plant = load_plant(_plant(tmp_path, 'seed: 10\nmachines:\n' + ''.join(
        f'  - {{namespace: p{i}, scene: sdof}}\n' for i in range(5))))
    seeds = [m.seed for m in plant.machines]
    assert seeds == [10, 11, 12, 13, 14]
    errors = _errors(tmp_path, """
seed: 10
machines:
  - {namespace: a, scene: sdof}
  - {namespace: b, scene: sdof, seed: 10}
""")
    assert errors == ["machines[1].seed: 10 is also machines[0]'s; no two machines may share "
                      'a seed (their streams would be equal)']
    errors = _errors(tmp_path, f"""
seed: {SEED_MAX}
machines:
  - {{namespace: a, scene: sdof}}
  - {{namespace: b, scene: sdof}}
""")
    assert len(errors) == 1 and errors[0].startswith('machines[1].seed: the plant seed')


def test_every_problem_is_named_at_once(tmp_path):
    errors = _errors(tmp_path, """
record: sometimes
machines:
  - {namespace: pump1, scene: hpotp, unbalance: 200}
  - {namespace: pump1, scene: nosuch}
  - {namespace: 1pump, scene: sdof, preset: fancy, noise_std: -1 g}
  - {namespace: b, scene: sdof, faults: [{kind: gain}], bogus: 1}
""")
    by_key = {e.split(':', 1)[0]: e for e in errors}
    assert set(by_key) == {'record', 'machines[0].unbalance', 'machines[2].namespace',
                           'machines[2].preset', 'machines[2].noise_std',
                           'machines[3].bogus', 'machines[3].faults[0].accelerometer'}, errors
    assert 'none | per_machine | one_log' in by_key['record']
    assert '[0, 100]' in by_key['machines[0].unbalance']
    assert 'iepe_100mv_50g' in by_key['machines[2].preset']       # names the presets
    assert 'not a ROS namespace' in by_key['machines[2].namespace']
    assert '-9.80665 m/s^2' in by_key['machines[2].noise_std']    # the unit, converted
    assert 'known keys here' in by_key['machines[3].bogus']


def test_machines_are_checked_against_their_scenes(tmp_path):
    errors = _errors(tmp_path, """
machines:
  - {namespace: pump1, scene: hpotp}
  - {namespace: pump1, scene: nosuch}
  - {namespace: x10, scene: hpotp_x10}
  - {namespace: beam, scene: cantilever, unbalance: 2}
  - {namespace: a, scene: sdof, overrides: ['impactors.0.clearance=-1 mm']}
  - {namespace: a/d, scene: sdof}
  - {namespace: c, scene: sdof, preset: ideal, overrides: ['channel=ideal']}
""")
    assert errors[0] == ("machines[1].namespace: 'pump1' is also machines[0]'s; each machine "
                         'needs its own namespace')
    assert errors[1].startswith("machines[1].scene: unknown scene 'nosuch'; ready-made scenes:")
    assert errors[2].startswith("machines[2].scene: scene 'hpotp_x10' is for offline studies "
                                'only')   # offline_only, with the scene's reason
    assert errors[3] == ("machines[3].unbalance: scene 'cantilever' has no rotor unbalance to "
                         'scale; leave unbalance out')
    assert errors[4].startswith("machines[4].overrides: scene 'sdof': scene key "
                                "'impactors[0].clearance'"), errors[4]
    assert errors[5].startswith("machines[5].namespace: 'a/d' and machines[4]'s 'a' nest")
    assert errors[6] == 'machines[6].preset: the overrides set channel too; give one of them'
    assert len(errors) == 7, errors


def test_two_machines_that_would_stream_the_same_signal_are_refused(tmp_path):
    """With the ideal channel and no noise nothing is random: the seed cannot set two
    machines apart, so the same scene and settings twice is one stream twice."""
    text = """
machines:
  - {namespace: a, scene: sdof, preset: ideal}
  - {namespace: b, scene: sdof, preset: ideal%s}
"""
    errors = _errors(tmp_path, text % '')
    assert len(errors) == 1 and errors[0].startswith(
        'machines[1]: streams the same signal as machines[0]'), errors
    load_plant(_plant(tmp_path, text % ', noise_std: 0.1'))       # noise: apart
    load_plant(_plant(tmp_path, (text % '').replace(', preset: ideal', '')))   # sensor noise


def test_paths_in_a_plant_file_are_relative_to_it(tmp_path):
    (tmp_path / 'scenes').mkdir()
    (tmp_path / 'scenes' / 'mine.yaml').write_text(
        (ROOT / 'config' / 'scenes' / 'sdof.yaml').read_text())
    (tmp_path / 'steps.yaml').write_text('schedule:\n  - {at: 1 s, noise_std: 0.1}\n')
    sub = tmp_path / 'plants'
    sub.mkdir()
    path = sub / 'p.yaml'
    path.write_text("""
machines:
  - {namespace: a, scene: ../scenes/mine.yaml, schedule: ../steps.yaml,
     faults: [{kind: dropout, accelerometer: sdof_x, onset: 2 s, duration: 0.1 s}]}
  - {namespace: b, scene: ../scenes/mine.yaml, schedule: ../steps.yaml}
""")
    plant = load_plant(path)
    a, b = plant.machines
    assert a.scene == str(tmp_path / 'scenes' / 'mine.yaml') and a.scene_name == 'sdof'
    assert plant.name == 'p'   # the file's stem
    params = plant.node_parameters(schedule_dir=tmp_path / 'out')
    assert params['b']['schedule'] == str(tmp_path / 'steps.yaml')   # as it is
    entries = yaml.safe_load(Path(params['a']['schedule']).read_text())['schedule']
    assert entries == [{'at': '1 s', 'noise_std': 0.1},               # the file's, then
                       {'at': '0 s', 'fault': {'kind': 'dropout', 'accelerometer': 'sdof_x',
                                               'onset': '2 s', 'duration': '0.1 s'}}]


def test_the_stagger_is_a_time_in_range(tmp_path):
    machines = 'machines:\n  - {namespace: a, scene: sdof}\n'
    assert load_plant(_plant(tmp_path, machines)).stagger == 0.0   # all at once by default
    assert load_plant(_plant(tmp_path, 'stagger: 1500 ms\n' + machines)).stagger == 1.5
    errors = _errors(tmp_path, 'stagger: 2 min\n' + machines)
    assert errors == [f'stagger: 2 min = 120 s is out of range [0, {STAGGER_MAX:g}] s '
                      '(= [0, 1] min)'], errors
    assert _errors(tmp_path, 'stagger: -1 s\n' + machines)[0].startswith('stagger: ')


def test_a_stagger_holds_each_rotor_at_rest_then_runs_it_up_i_x_stagger_later(tmp_path):
    """Issue 39: ten hpotp running up through the resonance together cost several times
    their steady state at once. Machine i's schedule holds its rotor at rest from 0 s and
    commands the scene's running speed at i x stagger; machine 0 and a machine whose rotor
    starts at speed (rbs) or that has none (sdof) get no such entries; a fault keeps its
    index after the schedule file's entries."""
    from impact_damper_sim.live.schedule import Schedule
    path = _plant(tmp_path, """
stagger: 1.5 s
machines:
  - {namespace: a, scene: hpotp}
  - {namespace: b, scene: hpotp, faults: [{kind: gain, accelerometer: hpotp_casing_bottom,
                                           gain: 2}]}
  - {namespace: c, scene: hpotp}
  - {namespace: d, scene: rbs}
  - {namespace: e, scene: sdof, noise_std: 0.1}
""")
    plant = load_plant(path)
    assert [m.run_up_speed for m in plant.machines] == [2400.0] * 3 + [None, None]
    params = plant.node_parameters(schedule_dir=tmp_path / 'schedules')
    assert 'schedule' not in params['a'] and 'schedule' not in params['d'] \
        and 'schedule' not in params['e'], params
    for ns, delay in (('b', 1.5), ('c', 3.0)):
        entries = yaml.safe_load(Path(params[ns]['schedule']).read_text())['schedule']
        assert entries[-2:] == [{'at': '0 s', 'speed': '0 rad/s'},
                                {'at': f'{delay} s', 'speed': '2400.0 rad/s'}], entries
        timeline = [(e.at, e.commands) for e in Schedule.load(params[ns]['schedule']).entries]
        assert timeline[-1] == (delay, (('speed', 'topic', 'rotor/speed_command', 2400.0),)), \
            timeline
    assert 'fault' in yaml.safe_load(Path(params['b']['schedule']).read_text())['schedule'][0]


def test_the_shipped_plants_load_and_are_found_by_name():
    assert {'ten_hpotp', 'mixed'} <= set(plant_files())
    ten = load_plant('ten_hpotp')
    assert len(ten.machines) == 10 and {m.scene_name for m in ten.machines} == {'hpotp'}
    assert len({m.seed for m in ten.machines}) == 10
    assert len({m.unbalance for m in ten.machines}) == 10
    mixed = load_plant('mixed')
    assert [m.scene_name for m in mixed.machines] == ['hpotp', 'rbs', 'rbs_kcc', 'cantilever']
    with pytest.raises(PlantError, match="unknown plant 'nosuch'; ready-made plants: .*mixed"):
        resolve_plant('nosuch')


def test_setup_installs_the_plants_with_the_config():
    """setup.py's data files take config/ whole: the plants land in
    share/impact_damper_sim/config/plants (setup.py's own ``_config_files``, run here)."""
    import ast
    source = (ROOT / 'setup.py').read_text()
    function = next(n for n in ast.parse(source).body
                    if isinstance(n, ast.FunctionDef) and n.name == '_config_files')
    namespace = {'Path': Path, 'here': ROOT, 'package_name': 'impact_damper_sim'}
    exec(compile(ast.Module([function], []), 'setup.py', 'exec'), namespace)
    pairs = dict(namespace['_config_files']())
    plants = pairs['share/impact_damper_sim/config/plants']
    assert {'config/plants/ten_hpotp.yaml', 'config/plants/mixed.yaml'} <= set(plants)


def test_the_guide_lists_every_plant_key():
    """docs/guides/plant.md's two key tables name every key of the schema, and no other."""
    import re

    from impact_damper_sim.scene.plant import MACHINE_KEYS, PLANT_KEYS
    text = (ROOT / 'docs' / 'guides' / 'plant.md').read_text()
    plant_table, machine_table = (re.findall(r'^\| `(\w+)` \|', part, re.M) for part in
                                  text.split("A machine's keys", 1))
    assert plant_table[-len(PLANT_KEYS):] == list(PLANT_KEYS)
    assert machine_table[:len(MACHINE_KEYS)] == list(MACHINE_KEYS)
