"""A plant file: several machines, each one ``vibration_node`` in its own namespace.

A plant file is YAML, checked at load like a scene (every problem is one line naming its key,
``machines[2].scene: ...``, with the allowed range or values; all problems at once)::

    plant: pumps_a              # the plant's name (default: the file's stem)
    seed: 100                   # base seed: machine i gets seed + i unless it gives its own
    record: per_machine         # none | per_machine | one_log
    record_dir: logs/pumps_a    # where the logs go (default: ./<plant>_<date>-<time>)
    stagger: 2 s                # machine i's rotor starts i x this after machine 0's (default 0)
    machines:
      - namespace: pump1        # ROS namespace: the node is /pump1/vibration_node
        scene: hpotp            # scene name or file (relative to the plant file)
        unbalance: 1.5          # rotor unbalance multiplier X (scene key rotor.multiplier)
        preset: iepe_10mv_500g  # accelerometer channel preset (scene key channel)
        faults:                 # sensor faults, as a schedule entry's fault (docs/node.md)
          - {kind: gain, accelerometer: hpotp_casing_bottom, gain: 3, onset: 2 s}
      - namespace: pump2
        scene: rbs

Keys of a machine (:data:`MACHINE_KEYS` has each one's unit, range and default):
``namespace``, ``scene``, ``seed``, ``unbalance``, ``preset``, ``noise_std``, ``dampers``,
``hardware_id``, ``overrides``, ``schedule``, ``faults``. :meth:`Machine.node_parameters`
maps a machine to the values of ``vibration_node``'s parameters
(:mod:`impact_damper_sim.ros.parameters`): the seed to ``noise_seed`` (which seeds the
noise and every random stage of the accelerometer channel, so machines of one scene stream
different signals), ``unbalance`` and ``preset`` to scene ``overrides``, the faults and the
schedule to one ``schedule`` file, a per-machine log to ``record``.

Checked here (no ROS, nothing built): the keys, units and ranges; namespaces valid ROS names,
unique and none inside another; every scene found and live (not ``offline_only``), with the
machine's overrides applied (so a preset, an unbalance on a scene without a rotor unbalance or
a bad override is refused here, naming the machine); seeds unique; two machines that would
stream the same signal (no random stage in the channel, no noise, same scene and settings);
each fault a mapping with ``kind`` and ``accelerometer``. A fault's own keys and its
accelerometer are checked by the node when it loads its schedule at start (the schedule and
fault checks live a layer above the scene; the launch file runs them before starting
anything, :func:`fault_schedule_entries` keeps the fault order so ``schedule[k]`` there is
``machines[i].faults[k]`` here).
"""
from __future__ import annotations

import copy
import dataclasses
import datetime
import math
import os
import re
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from .catalog import resolve_scene, validated
from .channel_spec import PRESETS
from .containers import ListOf, Section
from .excitation import speed_profile
from .loading import load_yaml
from .schema import (
    _INVALID,
    Boolean,
    Choice,
    Field,
    Integer,
    Quantity,
    SceneError,
    String,
    _Errors,
    _got,
    _join,
    validate,
)

__all__ = ['MACHINE_KEYS', 'PLANT_KEYS', 'RECORD_MODES', 'SCHEMA', 'SEED_MAX', 'STAGGER_MAX',
           'Machine', 'Plant', 'PlantError', 'fault_schedule_entries', 'load_plant', 'plant_files',
           'resolve_plant']

#: how a plant records: not at all, one MCAP per machine (each node's ``record``
#: parameter), or one MCAP for all (the ``recorder`` node)
RECORD_MODES = ('none', 'per_machine', 'one_log')
#: the longest stagger between two machines' run-ups (s): a minute apart is a plant started
#: by hand; more is a typo
STAGGER_MAX = 60.0

#: the largest seed (``noise_seed``'s range, 2^31 - 1)
SEED_MAX = 2**31 - 1

#: the node's default ``max_unbalance``: the largest multiplier a plant may give
UNBALANCE_MAX = 100.0

#: one namespace token (ROS 2 names: letters, digits, underscores; not starting with a digit)
_TOKEN = r'[A-Za-z_][A-Za-z0-9_]*'
_NAMESPACE = rf'/?{_TOKEN}(/{_TOKEN})*'
_PLANT_NAME = r'[A-Za-z0-9][A-Za-z0-9_.-]*'


class _Faults(Field):
    """A list of fault mappings, kept as written (engineering units and all): each a
    mapping with a string ``kind`` and ``accelerometer``; the rest is the node's to check."""

    def __init__(self) -> None:
        super().__init__([], 'sensor faults, each as a schedule entry\'s fault (keys kind, '
                             'accelerometer, onset, duration and the kind\'s; docs/node.md)')

    def kind(self) -> str:
        return 'list of fault mappings'

    def _convert(self, raw: object, path: str, errors: _Errors) -> object:
        if not isinstance(raw, list):
            errors.add(path, f'expected a list of fault mappings, {_got(raw)}')
            return _INVALID
        before = len(errors)
        for k, fault in enumerate(raw):
            where = f'{path}[{k}]'
            if not isinstance(fault, dict):
                errors.add(where, f'expected a fault mapping (kind, accelerometer, ...), '
                                  f'{_got(fault)}')
                continue
            for key in ('kind', 'accelerometer'):
                if not isinstance(fault.get(key), str) or not fault.get(key):
                    errors.add(_join(where, key), f'expected a string, '
                                                  f'{_got(fault.get(key))}'
                               if key in fault else 'missing required key; expected a string')
        return copy.deepcopy(raw) if len(errors) == before else _INVALID


class _Namespace(String):
    """A ROS namespace, refused in words rather than by its regular expression."""

    def range_text(self) -> str:
        return ('ROS name tokens joined by /: letters, digits and underscores, not starting '
                'with a digit')

    def _convert(self, raw: object, path: str, errors: _Errors) -> object:
        if isinstance(raw, str) and raw and not re.fullmatch(_NAMESPACE, raw):
            errors.add(path, f'{raw!r} is not a ROS namespace; expected {self.range_text()} '
                             "(e.g. 'pump1' or 'plant_a/pump1')")
            return _INVALID
        return super()._convert(raw, path, errors)


#: a machine's keys: the node parameter (or scene key) each sets, unit and range
MACHINE_KEYS = {
    'namespace': _Namespace(pattern=_NAMESPACE,
                        doc="ROS namespace of the machine's node (e.g. pump1 or "
                            'plant_a/pump1); unique'),
    'scene': String(doc='scene name (config/scenes) or file (relative to the plant file); '
                        'live, not offline_only'),
    'seed': Integer(None, min=0, max=SEED_MAX,
                    doc="the node's noise_seed (noise and the channel's random stages); "
                        'default the plant seed + the machine index; unique'),
    'unbalance': Quantity('dimensionless', None, min=0.0, max=UNBALANCE_MAX,
                          doc="rotor unbalance multiplier X (scene key rotor.multiplier); "
                              "default the scene's; needs a rotor unbalance"),
    'preset': Choice(tuple(PRESETS), None,
                     doc="accelerometer channel preset (scene key channel); default the "
                         "scene's"),
    'noise_std': Quantity('acceleration', 0.0, min=0.0, max=1000.0,
                          doc="white noise added to each sample (the node's noise_std)"),
    'dampers': Boolean(True, doc="impact dampers act (the node's dampers_enabled)"),
    'hardware_id': String('', allow_empty=True,
                          doc="/diagnostics hardware_id (e.g. a pump serial); empty = "
                              "'<namespace>/<scene>'"),
    'overrides': ListOf(String(), default=[],
                        doc="more scene overrides 'key=value' (the node's overrides)"),
    'schedule': String(None, doc='command schedule file (relative to the plant file); '
                                 'the faults are added to it'),
    'faults': _Faults(),
}

#: the plant's own keys
PLANT_KEYS = {
    'plant': String(None, pattern=_PLANT_NAME,
                    doc="the plant's name (log file and metadata); default the file's stem"),
    'seed': Integer(0, min=0, max=SEED_MAX,
                    doc='base seed: machine i (from 0) gets seed + i unless it gives its own'),
    'record': Choice(RECORD_MODES, 'none',
                     doc='none, per_machine (<record_dir>/<namespace>.mcap each) or one_log '
                         '(<record_dir>/<plant>.mcap)'),
    'record_dir': String('', allow_empty=True,
                         doc='directory of the logs (relative to where it is launched); empty '
                             '= ./<plant>_<YYYYmmdd-HHMMSS>'),
    'record_overwrite': Boolean(False, doc='overwrite existing logs (otherwise refused)'),
    'stagger': Quantity('time', 0.0, min=0, max=STAGGER_MAX,
                        doc="machine i's rotor (from 0) starts its run-up i x this after "
                            "machine 0's, as a plant's pumps are started one after another "
                            '(0: all together); the nodes all stream from the start'),
    'machines': ListOf(Section(MACHINE_KEYS), min_len=1, doc='the machines'),
}

#: the schema of a plant file
SCHEMA = Section(PLANT_KEYS)


class PlantError(SceneError):
    """A plant file is invalid: one line per problem, each naming the key
    (``machines[2].scene``) and what it accepts."""

    def __init__(self, errors: str | Sequence[str], source: str | None = None) -> None:
        lines = [errors] if isinstance(errors, str) else list(errors)
        lines = [re.sub(r"^scene key '([^']*)': ", r'\1: ', e) for e in lines]
        super().__init__(lines, source)
        if source is not None and len(self.errors) > 1:
            self.args = ('\n'.join([f'invalid plant {source} ({len(self.errors)} errors):',
                                    *self.errors]),)


@dataclasses.dataclass(frozen=True)
class Machine:
    """One machine of a plant: a ``vibration_node`` in its namespace.

    Attributes
    ----------
    index : int
        Its place in the plant file (from 0).
    namespace : str
        ROS namespace, without a leading slash (``pump1``).
    scene : str
        Scene name, or the scene file's absolute path.
    scene_name : str
        The scene's ``name`` key (``hpotp``).
    seed : int
        The node's ``noise_seed``.
    unbalance : float or None
        Rotor unbalance multiplier X (dimensionless); None = the scene's.
    preset : str or None
        Channel preset; None = the scene's.
    effective_preset : str
        The preset its accelerometers start from (the scene's when ``preset`` is None).
    noise_std : float
        White noise standard deviation (m/s^2).
    dampers : bool
        Impact dampers act.
    hardware_id : str
        /diagnostics hardware_id; ``''`` = the node's default ``<namespace>/<scene>``.
    overrides : tuple of str
        Scene overrides given in the file (the preset and unbalance come on top).
    schedule : str or None
        Command schedule file (absolute path) or None.
    faults : tuple of dict
        Fault mappings as written.
    """

    index: int
    namespace: str
    scene: str
    scene_name: str
    seed: int
    unbalance: float | None
    preset: str | None
    effective_preset: str
    noise_std: float
    dampers: bool
    hardware_id: str
    overrides: tuple[str, ...]
    schedule: str | None
    faults: tuple[dict[str, Any], ...]
    #: the running speed (rad/s) the scene's rotor runs up to from rest, which a staggered
    #: start commands; None when it starts at speed (no run-up to stagger) or has no rotor
    run_up_speed: float | None = None

    @property
    def flat_name(self) -> str:
        """str: The namespace as one file-name word (``plant_a/pump1`` -> ``plant_a.pump1``;
        ``.`` is not in a ROS name, so no two namespaces give one name)."""
        return self.namespace.replace('/', '.')

    @property
    def node_name(self) -> str:
        """str: The node's fully qualified name (``/pump1/vibration_node``)."""
        return f'/{self.namespace}/vibration_node'

    def scene_overrides(self) -> list[str]:
        """The node's ``overrides``: the file's, then the unbalance and the preset (list)."""
        out = list(self.overrides)
        if self.unbalance is not None:
            out.append(f'rotor.multiplier={self.unbalance!r}')
        if self.preset is not None:
            out.append(f'channel={self.preset}')
        return out

    def schedule_text(self, start_delay: float = 0.0) -> str | None:
        """The YAML text of the machine's schedule (its schedule file's entries, then one
        entry per fault, at 0 s, then a staggered start's two), or None when it has neither
        faults nor a staggered start (str).

        Parameters
        ----------
        start_delay : float, optional
            Hold the rotor at rest until this sim time (s), then command its running speed
            (a rotor that runs up from rest; 0: it starts with the node).
        """
        start = (start_delay > 0 and self.run_up_speed is not None) and [
            {'at': '0 s', 'speed': '0 rad/s'},
            {'at': f'{start_delay!r} s', 'speed': f'{self.run_up_speed!r} rad/s'}]
        if not self.faults and not start:
            return None
        entries: list[Any] = []
        if self.schedule is not None:
            entries = list(load_yaml(Path(self.schedule), kind='schedule')['schedule'])
        entries += fault_schedule_entries(self.faults)
        entries += start or []   # last: faults[k] keeps its index after the file's entries
        head = (f'# schedule of machine {self.namespace} (plant file machines[{self.index}]): '
                f'faults[k] is the entry after the schedule file\'s\n')
        return head + yaml.safe_dump({'schedule': entries}, sort_keys=False)

    def node_parameters(self, *, record: str = '', record_overwrite: bool = False,
                        schedule_dir: str | os.PathLike[str] | None = None,
                        start_delay: float = 0.0) -> dict[str, Any]:
        """The machine's ``vibration_node`` parameters (name -> value).

        Parameters
        ----------
        record : str, optional
            MCAP file of a per-machine log; ``''`` = not recording.
        record_overwrite : bool, optional
            Overwrite an existing log.
        schedule_dir : str or os.PathLike, optional
            Where to write the schedule of a machine with faults or a staggered start
            (``<flat_name>.schedule.yaml``; created); default a directory under the system's
            temporary directory.
        start_delay : float, optional
            The rotor's run-up starts at this sim time (s): :meth:`schedule_text`.

        Returns
        -------
        dict
            ``scene``, ``overrides`` (only when there are), ``noise_seed``, ``noise_std``,
            ``dampers_enabled``, ``hardware_id``, ``schedule`` and ``record`` (when set),
            ``record_overwrite``; types as the node declares them.
        """
        params: dict[str, Any] = {'scene': self.scene, 'noise_seed': int(self.seed),
                                  'noise_std': float(self.noise_std),
                                  'dampers_enabled': bool(self.dampers)}
        overrides = self.scene_overrides()
        if overrides:
            params['overrides'] = overrides
        if self.hardware_id:
            params['hardware_id'] = self.hardware_id
        text = self.schedule_text(start_delay)
        if text is not None:
            directory = Path(schedule_dir if schedule_dir is not None else
                             Path(tempfile.gettempdir()) / f'impact_damper_plant_{os.getuid()}')
            directory.mkdir(parents=True, exist_ok=True)
            file = directory / f'{self.flat_name}.schedule.yaml'
            file.write_text(text, encoding='utf-8')
            params['schedule'] = str(file)
        elif self.schedule is not None:
            params['schedule'] = self.schedule
        if record:
            params['record'] = str(record)
            params['record_overwrite'] = bool(record_overwrite)
        return params

    def labels(self) -> dict[str, Any]:
        """What tells the machine apart in a log's metadata (plain values, str keys)."""
        return {'machine': self.namespace, 'scene': self.scene_name, 'seed': self.seed,
                'unbalance': self.unbalance, 'preset': self.effective_preset,
                'faults': [dict(f) for f in self.faults], 'hardware_id': self.hardware_id
                or f'{self.namespace}/{self.scene_name}'}


@dataclasses.dataclass(frozen=True)
class Plant:
    """A loaded plant file.

    Attributes
    ----------
    name : str
        The plant's name.
    source : str
        The file it came from.
    seed : int
        Base seed.
    record : str
        One of :data:`RECORD_MODES`.
    record_dir : str
        Directory of the logs as written (``''`` = :meth:`record_directory`'s default).
    record_overwrite : bool
    machines : tuple of Machine
    stagger : float
        Machine ``i``'s rotor starts its run-up ``i`` x this after machine 0's (s).
    """

    name: str
    source: str
    seed: int
    record: str
    record_dir: str
    record_overwrite: bool
    machines: tuple[Machine, ...]
    stagger: float = 0.0

    @property
    def namespaces(self) -> list[str]:
        """list of str: The machines' namespaces, in file order."""
        return [m.namespace for m in self.machines]

    def record_directory(self, override: str | os.PathLike[str] | None = None,
                         now: datetime.datetime | None = None) -> Path:
        """The directory the logs go to: ``override`` (a launch argument), else the file's
        ``record_dir``, else ``./<plant>_<YYYYmmdd-HHMMSS>`` (local time ``now``) so that a
        second launch does not meet the first one's files."""
        if override:
            return Path(override)
        if self.record_dir:
            return Path(self.record_dir)
        stamp = (now or datetime.datetime.now()).strftime('%Y%m%d-%H%M%S')
        return Path(f'{self.name}_{stamp}')

    def record_paths(self, directory: str | os.PathLike[str]) -> dict[str, Path]:
        """The log files in ``directory``: per machine ``{namespace: <dir>/<flat>.mcap}``,
        one log ``{'': <dir>/<plant>.mcap}``, none ``{}``."""
        d = Path(directory)
        if self.record == 'per_machine':
            return {m.namespace: d / f'{m.flat_name}.mcap' for m in self.machines}
        if self.record == 'one_log':
            return {'': d / f'{self.name}.mcap'}
        return {}

    def node_parameters(self, record_dir: str | os.PathLike[str] | None = None,
                        schedule_dir: str | os.PathLike[str] | None = None
                        ) -> dict[str, dict[str, Any]]:
        """Every machine's node parameters, ``{namespace: {name: value}}``; per-machine
        logs in ``record_dir`` (default :meth:`record_directory`), machine ``i``'s run-up
        ``i`` x :attr:`stagger` after machine 0's."""
        paths = (self.record_paths(record_dir if record_dir is not None
                                   else self.record_directory())
                 if self.record == 'per_machine' else {})
        return {m.namespace: m.node_parameters(record=str(paths.get(m.namespace, '')),
                                               record_overwrite=self.record_overwrite,
                                               schedule_dir=schedule_dir,
                                               start_delay=m.index * self.stagger)
                for m in self.machines}

    def with_stagger(self, value: float | str, name: str = 'stagger') -> Plant:
        """This plant with its :attr:`stagger` set to ``value`` (s; a launch argument's text
        or a number).

        Raises
        ------
        PlantError
            ``value`` is not a number of seconds in [0, :data:`STAGGER_MAX`]; the message
            starts with ``name`` (``stagger:=9000``, ``--stagger 9000``).
        """
        try:
            stagger = float(value)
        except ValueError:
            stagger = math.nan
        if not 0 <= stagger <= STAGGER_MAX:
            raise PlantError(f'{name}: give seconds from 0 to {STAGGER_MAX:g} (machine i\'s '
                             "rotor runs up i x this after machine 0's)")
        return dataclasses.replace(self, stagger=stagger)

    def labels(self) -> dict[str, Any]:
        """The plant's labels for a log's metadata: name, file, seed and each machine's
        :meth:`Machine.labels` (plain values)."""
        return {'plant': self.name, 'source': self.source, 'seed': self.seed,
                'machines': [m.labels() for m in self.machines]}


def _run_up_speed(rotor: Mapping[str, Any] | None) -> float | None:
    """The speed (rad/s) a validated ``rotor`` section runs up to from rest; None without a
    rotor or when it starts at speed."""
    if rotor is None:
        return None
    profile = speed_profile(rotor['speed'])
    final = float(profile.final_speed)
    return final if float(profile.speed(0.0)) == 0.0 and final > 0 else None


def fault_schedule_entries(faults: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Schedule entries for ``faults``: one each, ``{at: 0 s, fault: <the mapping>}``, in
    order (a fault without ``onset`` starts with the run; one with ``onset`` then)."""
    return [{'at': '0 s', 'fault': dict(f)} for f in faults]


def plant_dirs() -> list[Path]:
    """The directories searched for plant names: the ``plants`` folder beside each scene
    directory (``config/plants``: the source tree's, then the installed share's)."""
    from .catalog import scene_dirs
    return [d.parent / 'plants' for d in scene_dirs() if (d.parent / 'plants').is_dir()]


def plant_files() -> list[str]:
    """The names of the ready-made plants (sorted list of str)."""
    return sorted({p.stem for d in plant_dirs() for p in d.glob('*.yaml')})


def resolve_plant(name_or_path: str | os.PathLike[str]) -> Path:
    """The file of a plant: a path (anything with a ``/`` or ending in ``.yaml``) as it is,
    a bare name as ``config/plants/<name>.yaml``.

    Raises
    ------
    PlantError
        No such file, naming the ready-made plants.
    """
    text = os.fspath(name_or_path)
    if '/' in text or text.endswith(('.yaml', '.yml')):
        path = Path(text).expanduser()
        if not path.is_file():
            raise PlantError(f'plant file {text!r} not found')
        return path
    for d in plant_dirs():
        if (d / f'{text}.yaml').is_file():
            return d / f'{text}.yaml'
    raise PlantError(f"unknown plant {text!r}; ready-made plants: "
                     f"{', '.join(plant_files()) or 'none'}; or give a path to a .yaml file")


def _relative(value: str, base: Path) -> str:
    """A path written in the plant file, relative to the file's directory (absolute str)."""
    path = Path(value).expanduser()
    return str(path if path.is_absolute() else (base / path).resolve())


def _scene_of(raw: str, base: Path) -> str:
    """A scene name as it is; a path (a ``/`` or ``.yaml``) relative to the plant file."""
    return _relative(raw, base) if '/' in raw or raw.endswith(('.yaml', '.yml')) else raw


def _random_stage(channel: Mapping[str, Any] | None) -> bool:
    """Whether a resolved channel draws random numbers (sensor noise, bias, DAQ noise)."""
    if not channel:
        return False
    adc = channel.get('adc') or {}
    return bool(channel.get('noise_density') or channel.get('bias') or adc.get('noise'))


def load_plant(path: str | os.PathLike[str]) -> Plant:
    """Read and check a plant file (a name under ``config/plants`` or a path).

    Parameters
    ----------
    path : str or os.PathLike
        ``ten_hpotp`` or ``my/plant.yaml``.

    Returns
    -------
    Plant

    Raises
    ------
    PlantError
        Every problem, one line each naming its key (``machines[2].scene``) and what it
        accepts.
    """
    file = resolve_plant(path)
    source = str(file)
    try:
        raw = load_yaml(file, kind='plant')
        value = validate(SCHEMA, raw, source=source)
    except SceneError as exc:
        raise PlantError(exc.errors, source=source) from None
    base = file.resolve().parent
    errors: list[str] = []
    name = value['plant'] or file.stem
    if not re.fullmatch(_PLANT_NAME, name):
        errors.append(f'plant: the file name {name!r} is no plant name; give plant: '
                      f'matching {_PLANT_NAME}')
    machines: list[Machine] = []
    seen_ns: dict[str, int] = {}
    seen_seed: dict[int, int] = {}
    streams: dict[tuple[Any, ...], int] = {}
    for i, m in enumerate(value['machines']):
        where = f'machines[{i}]'
        ns = m['namespace'].lstrip('/')
        for other, j in seen_ns.items():
            if other == ns:
                errors.append(f'{where}.namespace: {ns!r} is also machines[{j}]\'s; each '
                              'machine needs its own namespace')
            elif ns.startswith(other + '/') or other.startswith(ns + '/'):
                errors.append(f'{where}.namespace: {ns!r} and machines[{j}]\'s {other!r} '
                              'nest; one machine\'s topics would lie under the other\'s')
        seen_ns.setdefault(ns, i)
        seed = value['seed'] + i if m['seed'] is None else m['seed']
        if seed > SEED_MAX:
            errors.append(f'{where}.seed: the plant seed {value["seed"]} + {i} = {seed} is '
                          f'above {SEED_MAX}; give a smaller plant seed or this machine\'s own')
        elif seed in seen_seed:
            errors.append(f'{where}.seed: {seed} is also machines[{seen_seed[seed]}]\'s; no '
                          'two machines may share a seed (their streams would be equal)')
        seen_seed.setdefault(seed, i)
        scene = _scene_of(m['scene'], base)
        schedule = None if m['schedule'] is None else _relative(m['schedule'], base)
        if schedule is not None and not Path(schedule).is_file():
            errors.append(f'{where}.schedule: file {schedule!r} not found')
            schedule = None
        if m['preset'] is not None and any(o.split('=', 1)[0].strip() == 'channel'
                                           for o in m['overrides']):
            errors.append(f'{where}.preset: the overrides set channel too; give one of them')
        machine = Machine(
            index=i, namespace=ns, scene=scene, scene_name='', seed=seed,
            unbalance=m['unbalance'], preset=m['preset'], effective_preset='',
            noise_std=m['noise_std'], dampers=m['dampers'], hardware_id=m['hardware_id'],
            overrides=tuple(m['overrides']), schedule=schedule, faults=tuple(m['faults']))
        try:
            scene_path = resolve_scene(scene)
        except SceneError as exc:
            errors += [f'{where}.scene: {line}' for line in exc.errors]
            continue
        # without the unbalance: a scene without a rotor gets the plant's message, not the
        # rotor section's (the multiplier's range is the schema's, above)
        with_preset = list(machine.overrides) + ([] if m['preset'] is None
                                                 else [f"channel={m['preset']}"])
        try:
            spec, _ = validated(scene_path, with_preset)
        except SceneError as exc:
            for line in exc.errors:
                match = re.match(r"scene key '([^'.\[]*)", line)
                field = 'preset' if (m['preset'] is not None and match
                                     and match.group(1) == 'channel') else 'overrides'
                errors.append(f'{where}.{field}: scene {scene_path.stem!r}: {line}')
            continue
        if spec['offline_only']:
            errors.append(f"{where}.scene: scene {spec['name']!r} is for offline studies "
                          f"only, not a live machine: {spec['offline_only']}")
        rotor = spec['rotor']
        if m['unbalance'] is not None and (rotor is None or not rotor['unbalance']):
            errors.append(f"{where}.unbalance: scene {spec['name']!r} has no rotor unbalance "
                          'to scale; leave unbalance out')
        if schedule is not None and m['faults']:
            try:
                entries = load_yaml(Path(schedule), kind='schedule').get('schedule')
            except (SceneError, AttributeError):
                entries = None
            if not isinstance(entries, list):
                errors.append(f'{where}.schedule: {schedule!r} has no schedule: list to add '
                              'the faults to')
        machine = dataclasses.replace(machine, scene_name=spec['name'],
                                      effective_preset=spec['channel']['preset'],
                                      run_up_speed=_run_up_speed(rotor))
        random = (machine.noise_std > 0 or _random_stage(spec['channel'])
                  or any(_random_stage(s.get('channel')) for s in spec['sensors']))
        if not random:
            key = (str(scene_path.resolve()), tuple(machine.scene_overrides()),
                   machine.dampers, schedule, tuple(map(repr, machine.faults)))
            if key in streams:
                errors.append(f'{where}: streams the same signal as machines[{streams[key]}] '
                              '(same scene and settings, and no random stage: the channel '
                              f'{machine.effective_preset!r} has no noise and noise_std is '
                              '0); give a noise_std, a preset with noise or another '
                              'unbalance')
            streams.setdefault(key, i)
        machines.append(machine)
    if errors:
        raise PlantError(errors, source=source)
    return Plant(name=name, source=source, seed=value['seed'], record=value['record'],
                 record_dir=value['record_dir'], record_overwrite=value['record_overwrite'],
                 machines=tuple(machines), stagger=float(value['stagger']))
