"""``plant_host``: several machines in one process, one executor.

Each machine is a :class:`~impact_damper_sim.ros.vibration_node.VibrationNode` in its own
namespace (``/pump1/vibration_node``), with its own topics, services, parameters and
``/diagnostics`` status, exactly as when it runs as a process of its own; only the process
is shared, and by default one stepping thread (``--stepping shared``,
:class:`~.stepping.SharedStepping`) that runs every machine's cycle in turn and sleeps once
for all of them. ``--stepping own`` gives each machine a stepping thread of its own, as a
``vibration_node`` process has; those threads then take the interpreter lock from each
other. Five hpotp machines in one process on a 2-core VM (docs/bench/node-memory.md): worst
1 s window of the achieved real-time factor 0.97 shared, 0.48 with a thread each (median
0.91), at 89 % and 100 % of a core for the process and its reader.

What the process costs once (Python, NumPy, SciPy, Numba and the compiled kernels, rclpy and
the DDS participant: about 220 MB resident) is then paid once for the plant, and each
further machine adds its model and its DDS endpoints (a few MB: docs/bench/node-memory.md).
The ROS-native form (one process per machine, ``plant.launch.py``) stays; both give the same
graph.

What one process cannot share is the interpreter lock: its machines step Python in turn, so
one process gives them one core at most, less the switching. On a 2-core machine three hpotp
machines keep real time in one process and five do not, even stepped by one thread, where
five processes do (docs/bench/node-memory.md). For a plant larger than one core's worth,
split it: ``--share I/K`` hosts only the machines whose index (in the whole list, from 0) is
``I`` modulo ``K``, each exactly as in the whole plant (its seed, parameters, hardware_id;
``/clock`` only from the share holding machine 0), so K processes ``--share 0/K`` ...
``--share K-1/K`` of one plant give the same machines as one process of all
(``plant.launch.py hosts:=K`` starts them), or run one process per machine.

Usage::

    ros2 run impact_damper_sim plant_host --machines pump1:hpotp pump2:rbs
    ros2 run impact_damper_sim plant_host --plant ten_hpotp
    ros2 run impact_damper_sim plant_host --plant ten_hpotp --share 0/5   # and 1/5 ... 4/5
    ros2 run impact_damper_sim plant_host --plant my_plant.yaml --machines spare:sdof \\
        --ros-args -p real_time_factor:=0.5

``--machines`` takes ``namespace:scene`` pairs; ``--plant`` a plant file or the name of a
ready-made one (:mod:`impact_damper_sim.scene.plant`: per machine its seed, unbalance,
channel preset, noise, faults, hardware_id and per-machine log). Machines of both come in the
order given (the plant's first). Each machine is seeded apart: machine ``i`` (from 0) gets
``noise_seed`` = base + ``i`` (``--seed``, default the plant file's ``seed``, else 0) unless the
plant file gives it its own. Parameters after ``--ros-args -p`` apply to every machine where
the plant does not set them. Only the first machine publishes ``/clock`` (``--clock``): one
topic cannot carry several machines' sim times. ``--record-mode`` overrides the plant file's
``record`` (``none``, ``per_machine``, ``one_log``), ``--stagger S`` its ``stagger``;
``--stepping shared|own`` chooses the stepping threads (above).

Exit status as ``vibration_node``: 0 on Ctrl-C, SIGTERM or SIGHUP (every machine stopped and
its recording finished), 2 (one line on stderr naming the machine or the option) when a plant
file, a scene, a start-up parameter or ``--share`` is invalid (``--share`` leaving the process
no machine too).
"""
from __future__ import annotations

import argparse
import dataclasses
import sys

#: the executors plant_host can spin its machines with
EXECUTORS = ('single', 'multi')
#: how the machines step: one thread for all of them, or a thread each
STEPPING = ('shared', 'own')
#: which machines publish /clock
CLOCK_CHOICES = ('first', 'all', 'none')
#: the interpreter's thread switch interval here (s; Python's default 5 ms): the machines'
#: stepping threads share one lock, and one that refills five chunks kept the others from
#: sending for up to 5 ms. 1 ms: five hpotp machines in one process, worst 1 s window 0.897
#: -> 0.976 and 0.941 at the same CPU (bench/node_memory.py --plant 5 --no-processes)
SWITCH_INTERVAL = 1e-3
#: what --share accepts (its refusals say it)
SHARE_RULE = 'give I/K, integers with K >= 1 and 0 <= I < K (e.g. --share 0/5)'


class MachineSpec:
    """One machine to host: its namespace, scene and node parameter values.

    Parameters
    ----------
    namespace : str
        ROS namespace, without a leading slash (``pump1``).
    parameters : dict
        ``vibration_node`` parameter values (name -> value); ``scene`` among them.
    """

    def __init__(self, namespace, parameters):
        self.namespace = namespace.strip('/')
        self.parameters = dict(parameters)

    @property
    def scene(self):
        """str: The machine's scene (name or file)."""
        return self.parameters.get('scene', '')

    def __repr__(self):
        return f'MachineSpec({self.namespace!r}, {self.parameters!r})'


def parse_machine(text):
    """``'namespace:scene'`` -> ``(namespace, scene)``.

    Raises
    ------
    ValueError
        Not of that form (the message says what is expected).
    """
    namespace, sep, scene = text.partition(':')
    namespace = namespace.strip().strip('/')
    if not (sep and namespace and scene.strip()):
        raise ValueError(f'--machines: {text!r} is not namespace:scene (e.g. pump1:hpotp)')
    return namespace, scene.strip()


def parse_share(text):
    """``'I/K'`` (``--share``) -> ``(I, K)``, checked as :func:`machine_specs` checks it.

    Raises
    ------
    impact_damper_sim.scene.schema.SceneError
        Not two integers ``I/K`` with ``K >= 1`` and ``0 <= I < K`` (the message names
        ``--share``).
    """
    from ..scene.schema import SceneError
    index, sep, count = str(text).partition('/')
    try:
        share = (int(index), int(count))
    except ValueError:
        raise SceneError(f'--share {text}: {SHARE_RULE}') from None
    if not sep:
        raise SceneError(f'--share {text}: {SHARE_RULE}')
    return _checked_share(share)


def _checked_share(share):
    from ..scene.schema import SceneError
    try:
        index, count = share
    except (TypeError, ValueError):
        raise SceneError(f'--share {share!r}: {SHARE_RULE}') from None
    if not all(isinstance(v, int) and not isinstance(v, bool) for v in (index, count)) \
            or count < 1 or not 0 <= index < count:
        raise SceneError(f'--share {index}/{count}: {SHARE_RULE}')
    return index, count


def machine_specs(machines=(), plant=None, seed=None, record_dir=None, clock='first',
                  share=None, record_mode=None, stagger=None):
    """The machines to host, in order: the plant file's, then ``machines``.

    Parameters
    ----------
    machines : sequence of str
        ``namespace:scene`` pairs (``--machines``).
    plant : str, optional
        Plant file or ready-made plant name (``--plant``).
    seed : int, optional
        Base seed: machine ``i`` gets ``seed + i`` unless its plant entry gives a seed.
        Default the plant file's ``seed``, else 0.
    record_dir : str, optional
        Directory of a ``per_machine`` plant's logs (default the plant file's rule).
    clock : {'first', 'all', 'none'}
        Which machines publish ``/clock`` (``'first'``: machine 0 of the whole list).
    share : tuple of int, optional
        ``(I, K)`` (``--share I/K``): only the machines whose index in the whole list is
        congruent to ``I`` modulo ``K``, each as in the whole list (seed, parameters,
        ``publish_clock``). Default all.
    record_mode : str, optional
        Overrides the plant file's ``record`` (``none``, ``per_machine``, ``one_log``).
    stagger : float, optional
        Overrides the plant file's ``stagger`` (s): machine ``i``'s rotor runs up ``i`` x this
        after machine 0's.

    Returns
    -------
    specs : list of MachineSpec
        The hosted machines, in the whole list's order.
    notes : list of str
        What the caller should tell the user (e.g. a ``one_log`` plant needs ``recorder``).

    Raises
    ------
    impact_damper_sim.scene.schema.SceneError
        An invalid plant file, a malformed ``--machines`` entry, two machines in one
        namespace, none at all, or an invalid ``share`` or one that holds no machine.
    """
    from ..scene.schema import SceneError
    if share is not None:
        share = _checked_share(share)
    specs, notes = [], []
    base = 0 if seed is None else int(seed)
    if plant is not None:
        from ..scene.plant import load_plant
        loaded = load_plant(plant)
        if record_mode is not None:
            from ..scene.plant import RECORD_MODES
            if record_mode not in RECORD_MODES:
                raise SceneError(f"--record-mode {record_mode}: use one of "
                                 f"{' | '.join(RECORD_MODES)}")
            loaded = dataclasses.replace(loaded, record=record_mode)
        if stagger is not None:
            loaded = loaded.with_stagger(stagger, f'--stagger {stagger:g}')
        base = loaded.seed if seed is None else base
        params = loaded.node_parameters(record_dir=loaded.record_directory(record_dir)
                                        if loaded.record == 'per_machine' else None)
        for m in loaded.machines:
            p = params[m.namespace]
            if seed is not None and m.seed == loaded.seed + m.index:   # not its own seed
                p['noise_seed'] = base + m.index
            specs.append(MachineSpec(m.namespace, p))
        if loaded.record == 'per_machine':
            logs = loaded.record_directory(record_dir)
            logs.mkdir(parents=True, exist_ok=True)
            notes.append(f'plant {loaded.name!r}: one log per machine in {logs}/')
        elif loaded.record == 'one_log':
            notes.append(f'plant {loaded.name!r} records one log for all machines: run the '
                         f'recorder beside plant_host (ros2 run impact_damper_sim recorder '
                         f'--ros-args -p plant:={loaded.source})')
    for text in machines:
        try:
            namespace, scene = parse_machine(text)
        except ValueError as exc:
            raise SceneError(str(exc)) from None
        specs.append(MachineSpec(namespace, {'scene': scene,
                                             'noise_seed': base + len(specs)}))
    if not specs:
        raise SceneError('no machines: give --machines namespace:scene ... and/or --plant FILE')
    seen: dict[str, int] = {}
    for k, spec in enumerate(specs):
        if spec.namespace in seen:
            raise SceneError(f'machine {k} ({spec.namespace}:{spec.scene}): namespace '
                             f'{spec.namespace!r} is also machine {seen[spec.namespace]}\'s; '
                             'each machine needs its own')
        seen[spec.namespace] = k
        if clock != 'all':
            spec.parameters.setdefault('publish_clock', clock == 'first' and k == 0)
    if share is not None:
        index, count = share
        mine = specs[index::count]
        if not mine:
            raise SceneError(f'--share {index}/{count}: no machine of the {len(specs)} has '
                             f'an index {index} modulo {count}; give I/K with 0 <= I < '
                             f'min(K, {len(specs)})')
        specs = mine
    return specs, notes


def _parser():
    parser = argparse.ArgumentParser(
        prog='plant_host', description='Several vibration_node machines in one process, '
        'one executor (each in its own namespace). ROS arguments follow --ros-args.')
    parser.add_argument('--machines', nargs='+', default=[], metavar='NS:SCENE',
                        help='machines as namespace:scene, e.g. pump1:hpotp pump2:rbs')
    parser.add_argument('--plant', default=None, metavar='FILE',
                        help='plant file (YAML) or the name of a ready-made plant '
                             '(config/plants)')
    parser.add_argument('--seed', type=int, default=None,
                        help="base seed: machine i gets noise_seed = seed + i (default the "
                             "plant file's seed, else 0)")
    parser.add_argument('--record-dir', default=None,
                        help="directory of a per_machine plant's logs (default the plant "
                             "file's record_dir)")
    parser.add_argument('--record-mode', default=None, metavar='MODE',
                        help="none, per_machine or one_log: overrides the plant file's "
                             'record')
    parser.add_argument('--stagger', type=float, default=None, metavar='S',
                        help="machine i's rotor runs up i x S s after machine 0's: overrides "
                             "the plant file's stagger")
    parser.add_argument('--clock', choices=CLOCK_CHOICES, default='first',
                        help='which machines publish /clock (default: the first)')
    parser.add_argument('--share', default=None, metavar='I/K',
                        help='host only the machines whose index (plant file machines, then '
                             '--machines, from 0) is I modulo K, each as in the whole plant '
                             '(K processes --share 0/K ... K-1/K host all)')
    parser.add_argument('--stepping', choices=STEPPING, default='shared',
                        help='shared (default): one thread steps every machine in turn and '
                             'sleeps once for all; own: a stepping thread per machine')
    parser.add_argument('--executor', choices=EXECUTORS, default='single',
                        help='rclpy executor of all machines (default single: the machines '
                             'step in the stepping thread(s), not in the executor, which only '
                             'serves commands, parameters and the 1 s timers)')
    return parser


def make_executor(kind):
    """An rclpy executor: ``'single'`` (SingleThreadedExecutor) or ``'multi'``
    (MultiThreadedExecutor, two threads: the machines step in their stepping thread(s),
    not in the executor)."""
    from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
    return SingleThreadedExecutor() if kind == 'single' else MultiThreadedExecutor(2)


def build_machines(specs, node_class=None, **kwargs):
    """Build one node per machine (not stepping yet), in order.

    Parameters
    ----------
    specs : sequence of MachineSpec
    node_class : type, optional
        Default :class:`~impact_damper_sim.ros.vibration_node.VibrationNode`.
    **kwargs
        Passed to each node (e.g. ``context``).

    Returns
    -------
    list of VibrationNode

    Raises
    ------
    MachineError
        A machine's scene or parameters are invalid; the nodes built before it are
        destroyed.
    """
    from rclpy.exceptions import NameValidationException, ParameterException
    from rclpy.parameter import Parameter

    from ..scene.schema import SceneError
    if node_class is None:
        from .vibration_node import VibrationNode as node_class
    nodes = []
    for k, spec in enumerate(specs):
        overrides = [Parameter(name, value=value) for name, value in spec.parameters.items()]
        try:
            nodes.append(node_class(start_stepping=False, namespace=spec.namespace,
                                    parameter_overrides=overrides, **kwargs))
        except (SceneError, ParameterException, NameValidationException, ValueError,
                TypeError) as exc:
            for node in nodes:
                node.destroy_node()
            raise MachineError(f'machine {k} ({spec.namespace}:{spec.scene}): {exc}') from None
    return nodes


class MachineError(Exception):
    """A machine of the plant could not be built (the message names it)."""


def main(args=None):
    """Entry point: ``ros2 run impact_damper_sim plant_host --machines NS:SCENE ...``.

    Exit status 0 on Ctrl-C or shutdown, 2 (one line on stderr) when the plant file, a
    machine's scene or a start-up parameter is invalid.
    """
    sys.setswitchinterval(SWITCH_INTERVAL)

    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.utilities import remove_ros_args

    from ..scene.schema import SceneError
    from .process import (
        SignalStop,
        freeze_start_up_heap,
        shutdown_quietly,
        spin_guarded,
    )
    argv = list(sys.argv if args is None else args)
    options = _parser().parse_args(remove_ros_args(argv)[1:])
    try:
        share = None if options.share is None else parse_share(options.share)
        specs, notes = machine_specs(options.machines, options.plant, options.seed,
                                     options.record_dir, options.clock, share=share,
                                     record_mode=options.record_mode,
                                     stagger=options.stagger)
    except SceneError as exc:
        print(f'plant_host: {exc}', file=sys.stderr)
        return 2
    # Ctrl-C, SIGTERM and a closed terminal end the spin; each recording is finished
    stop = SignalStop()   # before rclpy.init: rclpy's handlers chain to it
    rclpy.init(args=argv)
    log = rclpy.logging.get_logger('plant_host')
    for note in notes:
        log.info(note)
    nodes = []
    try:
        nodes = build_machines(specs)
        stop.begin_running()   # signals only noted from here: the machines' threads start
        freeze_start_up_heap()   # once, after every machine: no full collections while paced
        stepping = None
        if options.stepping == 'shared':
            from .stepping import SharedStepping
            stepping = SharedStepping(nodes[0].MAX_WAIT) if nodes else None
        for node in nodes:
            node.start(stepping)
        if stepping is not None:
            stepping.start()   # every machine's schedule begins together
        executor = make_executor(options.executor)
        for node in nodes:
            executor.add_node(node)
        share_text = '' if share is None else f', share {share[0]}/{share[1]} of the plant'
        log.info(f'{len(nodes)} machines in one process ({options.executor}-threaded '
                 f'executor{share_text}): '
                 f"{', '.join(n.get_fully_qualified_name() for n in nodes)}")
        spin_guarded(executor, lambda exc: log.error(
            f'callback failed: {type(exc).__name__}: {exc}', throttle_duration_sec=1.0))
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except MachineError as exc:
        print(f'plant_host: {exc}', file=sys.stderr)
        return 2
    except Exception:
        if not stop.received:
            raise
        # the signal's shutdown under start-up ("context is invalid"): a stop, not a failure
    finally:
        stop.begin_clean_up()
        for node in nodes:
            node.destroy_node()
        shutdown_quietly()
    return 0


__all__ = ['CLOCK_CHOICES', 'EXECUTORS', 'SHARE_RULE', 'MachineError', 'MachineSpec',
           'build_machines', 'machine_specs', 'main', 'make_executor', 'parse_machine',
           'parse_share']


if __name__ == '__main__':
    sys.exit(main())
