"""A plant: one ``vibration_node`` per machine of a plant file, each in its own namespace
(each in its own process, or ``hosts:=K``: K ``plant_host`` processes sharing them).

Usage (after ``make``'s set-up, with ``AMENT_PREFIX_PATH=.venv``; or on a ROS 2 Jazzy machine
after ``colcon build``)::

    ros2 launch impact_damper_sim plant.launch.py plant:=mixed
    ros2 launch impact_damper_sim plant.launch.py plant:=ten_hpotp record:=logs/today
    ros2 launch impact_damper_sim plant.launch.py plant:=/path/to/my_plant.yaml \
        record_mode:=one_log monitor:=false
    ros2 launch impact_damper_sim plant.launch.py plant:=ten_hpotp hosts:=5
    ros2 launch impact_damper_sim plant.launch.py plant:=ten_hpotp stagger:=0

Arguments: ``plant`` (required: a name under ``config/plants`` or a plant file),
``record`` (directory of the logs; overrides the file's ``record_dir``; given while the file
says ``record: none``, each machine records its own log), ``record_mode`` (``none``,
``per_machine``, ``one_log``; empty = the file's), ``monitor`` (true/false), ``hosts``
(0, the default: one ``vibration_node`` process per machine; K >= 1: K ``plant_host``
processes, ``--share 0/K`` ... ``--share K-1/K`` of the plant file, machine ``i`` in process
``i mod K``; at most as many as machines), ``stagger`` (s; empty = the file's ``stagger``:
machine ``i``'s rotor runs up ``i`` x this after machine 0's; every node streams from the
start).

What starts (docs/guides/plant.md): ``/<namespace>/vibration_node`` per machine with the
parameters :meth:`Machine.node_parameters` gives (seed, unbalance, preset, faults as a
schedule, hardware_id; ``publish_clock`` on the first machine only, so ``/clock`` has one
publisher), in a process of its own or, with ``hosts:=K``, beside the other machines of its
share in a ``plant_host`` process (the same nodes, seeds, parameters and logs: each host
reads the plant file itself; its fault schedules go to a temporary directory); with
``one_log``, ``/recorder`` writing ``<dir>/<plant>.mcap``; with ``monitor``, one
``/monitor`` following every machine's namespace (parameter ``namespaces``), or one
``/<namespace>/monitor`` per machine with a monitor that follows only its own.

The plant file is checked before anything starts (every problem in one message, each line
naming its key, ``machines[2].scene: ...``), and so is each machine's list of faults against
its scene's accelerometers (``machines[0].faults[1].accelerometer: ...``).
"""
import dataclasses
import os
import re
import tempfile
from types import SimpleNamespace

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

PACKAGE = 'impact_damper_sim'


def fault_problems(plant):
    """Each machine's faults checked against its scene's accelerometers (list of str, each
    naming ``machines[i].faults[k].key``); the node would refuse them at start."""
    from impact_damper_sim.live.fault_spec import FaultError, parse_faults
    from impact_damper_sim.live.streams import accelerometers
    from impact_damper_sim.scene.catalog import validated
    problems = []
    for m in plant.machines:
        if not m.faults:
            continue
        spec, path = validated(m.scene, m.scene_overrides())
        scene = SimpleNamespace(scene=spec, name=spec['name'], source=str(path))
        names = [a.name for a in accelerometers(scene, 1000.0)]   # names: any rate
        try:
            parse_faults([dict(f) for f in m.faults], names, key=f'machines[{m.index}].faults')
        except FaultError as exc:
            problems += [re.sub(r"^(?:scene )?key '([^']*)': ", r'\1: ', e)
                         for e in exc.errors]
    return problems


def monitor_follows_namespaces():
    """Whether this package's monitor takes a ``namespaces`` parameter (one monitor for a
    whole plant); an older one follows its own namespace only."""
    import inspect

    from impact_damper_sim.ros import monitor
    return "'namespaces'" in inspect.getsource(monitor)


def plant_hosts(text, machines):
    """The ``hosts`` launch argument -> the number of ``plant_host`` processes (0: one
    ``vibration_node`` process per machine).

    Raises
    ------
    RuntimeError
        Not an integer from 0 to ``machines`` (a host without machines would exit 2).
    """
    try:
        hosts = int(text or 0)
    except ValueError:
        hosts = -1
    if not 0 <= hosts <= machines:
        raise RuntimeError(f'hosts:={text}: give 0 (one process per machine) or 1 to '
                           f'{machines} (plant_host processes, each a share of the '
                           f'{machines} machines)')
    return hosts


def _plant_actions(context):
    from impact_damper_sim.scene.plant import RECORD_MODES, PlantError, load_plant
    get = lambda name: LaunchConfiguration(name).perform(context).strip()   # noqa: E731
    try:
        plant = load_plant(get('plant'))
    except PlantError as exc:
        raise RuntimeError(str(exc)) from None
    problems = fault_problems(plant)
    if problems:
        raise RuntimeError('\n'.join([f'invalid plant {plant.source} (faults):', *problems]))
    record_dir, mode = get('record'), get('record_mode') or plant.record
    if mode not in RECORD_MODES:
        raise RuntimeError(f"record_mode:={mode!r}: use one of {' | '.join(RECORD_MODES)}")
    hosts = plant_hosts(get('hosts'), len(plant.machines))
    if get('stagger'):
        try:
            plant = plant.with_stagger(get('stagger'), f"stagger:={get('stagger')}")
        except PlantError as exc:
            raise RuntimeError(str(exc)) from None
    stagger = plant.stagger
    if record_dir and mode == 'none':
        mode = 'per_machine'   # asked to record: each machine its own (complete) log
    plant = dataclasses.replace(plant, record=mode)
    directory = plant.record_directory(record_dir or None) if mode != 'none' else None
    if directory is not None:
        os.makedirs(directory, exist_ok=True)
    actions = []
    if mode == 'one_log':
        log = plant.record_paths(directory)['']
        actions.append(Node(
            package=PACKAGE, executable='recorder', name='recorder', output='screen',
            emulate_tty=True,
            parameters=[{'output': str(log), 'plant': plant.source,
                         'namespaces': plant.namespaces,
                         'overwrite': plant.record_overwrite}]))
    if hosts:
        # no name or namespace: a remap of __node/__ns would apply to every machine
        # one_log: the recorder above writes the log; the hosts record nothing (and so do
        # not tell the user to start a recorder that is already running)
        record = ['--record-mode', 'none' if mode == 'one_log' else mode] + (
            ['--record-dir', str(directory)] if mode == 'per_machine' else [])
        actions += [Node(package=PACKAGE, executable='plant_host', output='screen',
                         emulate_tty=True,
                         arguments=['--plant', plant.source, *record, '--stagger', f'{stagger!r}',
                                    '--share', f'{i}/{hosts}'])
                    for i in range(hosts)]
    else:
        schedule_dir = directory if directory is not None else tempfile.mkdtemp(
            prefix=f'plant_{plant.name}_')
        params = plant.node_parameters(record_dir=directory, schedule_dir=schedule_dir)
        for i, m in enumerate(plant.machines):
            actions.append(Node(
                package=PACKAGE, executable='vibration_node', name='vibration_node',
                namespace=m.namespace, output='screen', emulate_tty=True,
                parameters=[{**params[m.namespace], 'publish_clock': i == 0}]))
    if get('monitor').lower() in ('true', '1', 'yes'):
        if monitor_follows_namespaces():
            actions.append(Node(
                package=PACKAGE, executable='monitor', name='monitor', output='screen',
                emulate_tty=True,
                parameters=[{'namespaces': ['/' + ns for ns in plant.namespaces]}]))
        else:
            actions += [Node(package=PACKAGE, executable='monitor', name='monitor',
                             namespace=ns, output='screen', emulate_tty=True)
                        for ns in plant.namespaces]
    return actions


def generate_launch_description():
    """The launch description: the arguments, then the plant's nodes (read at launch)."""
    return LaunchDescription([
        DeclareLaunchArgument('plant', description='plant name (config/plants/<name>.yaml) '
                                                   'or plant file'),
        DeclareLaunchArgument('record', default_value='',
                              description="directory of the logs; empty = the file's "
                                          'record_dir'),
        DeclareLaunchArgument('record_mode', default_value='',
                              description="none, per_machine or one_log; empty = the file's"),
        DeclareLaunchArgument('monitor', default_value='true',
                              description='also run the monitor'),
        DeclareLaunchArgument('hosts', default_value='0',
                              description='0: one vibration_node process per machine; K: K '
                                          'plant_host processes, each a share (--share i/K) '
                                          'of the machines'),
        DeclareLaunchArgument('stagger', default_value='',
                              description="s between two machines' rotor run-ups; empty = "
                                          "the file's stagger"),
        OpaqueFunction(function=_plant_actions),
    ])
