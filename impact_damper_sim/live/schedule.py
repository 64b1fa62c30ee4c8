"""A command schedule: what an operator would send the node, written down in sim time.

A small YAML file, checked at load like a scene (every problem names its key and the
allowed range; engineering units accepted and converted to SI once)::

    schedule:
      - {at: 0 s, noise_std: 0.05 g, noise_seed: 3}
      - {at: 0.5 s, speed_rate: 2000 rpm/s, speed: 3000 rpm}
      - {at: 2 s, unbalance: 2.5}
      - {at: 3 s, dampers: false}
      - {at: 4 s, fault: {kind: gain, accelerometer: hpotp_casing_bottom, gain: 20,
                          duration: 0.5 s}}
      - {at: 5 s, clear_fault: all}

Each entry is applied at sim time ``at`` (more exactly, at the first output sample boundary
at or after it, so that every driver applies it between the same two samples), its keys in
the order of :data:`KEYS`. A key is what the node accepts live:

======================  =====================================  ==============================
key                     applies as                             value
======================  =====================================  ==============================
``speed_rate``          parameter ``speed_rate_limit``          rate limit from now on, rad/s^2
``speed``               topic ``rotor/speed_command``           target speed, rad/s
``unbalance``           topic ``rotor/unbalance_command``       multiplier X
``dampers``             parameter ``dampers_enabled``           true or false
``noise_std``           parameter ``noise_std``                 m/s^2
``noise_seed``          parameter ``noise_seed``                restarts the noise sequence
``clear_fault``         topic ``accel/fault_command``           a fault's name, or ``all``:
                        (``{clear: <name>}``)                   ends it (them) now
``fault``               topic ``accel/fault_command``           a sensor fault (keys:
                                                               :mod:`.fault_spec`); without
                                                               ``onset`` it starts at ``at``
======================  =====================================  ==============================

A ``fault`` is checked at load (its kind's keys, units and ranges) and against the scene's
accelerometers when the schedule is checked against the simulation (:meth:`Schedule.check`).

``vibration_node`` plays a schedule (parameter ``schedule``) on its stepping thread and
``study record`` while it steps; both record every applied key as the live command or
parameter change it stands for, so ``replay`` and ``study report`` show it. Nothing here
imports ROS.
"""
from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

from ..scene.containers import ListOf, Section
from ..scene.schema import Boolean, Integer, Quantity, SceneError, String, validate
from .fault_spec import _NAME as FAULT_NAME
from .fault_spec import FAULT, FaultError, accelerometer_problem

if TYPE_CHECKING:
    from .realtime import LiveSimulation

#: (schedule key, 'topic' or 'parameter', the node's topic or parameter name), in the order
#: an entry's keys apply (a new rate limit before the speed command it should govern)
KEYS = (('speed_rate', 'parameter', 'speed_rate_limit'),
        ('speed', 'topic', 'rotor/speed_command'),
        ('unbalance', 'topic', 'rotor/unbalance_command'),
        ('dampers', 'parameter', 'dampers_enabled'),
        ('noise_std', 'parameter', 'noise_std'),
        ('noise_seed', 'parameter', 'noise_seed'),
        ('clear_fault', 'topic', 'accel/fault_command'),
        ('fault', 'topic', 'accel/fault_command'))

#: the schema of a schedule file; ranges are the node's parameter and command ranges
SCHEMA = Section({'schedule': ListOf(Section({
    'at': Quantity('time', min=0.0, max=1.0e6, doc='sim time the entry applies at'),
    'speed_rate': Quantity('angular_acceleration', None, min=0.0, max=1.0e6,
                           min_inclusive=False,
                           doc='rate limit of speed changes from now on (speed_rate_limit)'),
    'speed': Quantity('angular_speed', None, min=0.0, max=1.0e5,
                      doc='rotor speed command (rotor/speed_command)'),
    'unbalance': Quantity('dimensionless', None, min=0.0, max=1.0e4,
                          doc='unbalance multiplier X (rotor/unbalance_command)'),
    'dampers': Boolean(None, doc='impact dampers act (dampers_enabled)'),
    'noise_std': Quantity('acceleration', None, min=0.0, max=1000.0,
                          doc='accelerometer noise standard deviation (noise_std)'),
    'noise_seed': Integer(None, min=0, max=2**31 - 1,
                          doc='seed of the noise generator (noise_seed)'),
    'clear_fault': String(None, pattern=FAULT_NAME,
                          doc="ends the sensor fault of this name, or every one ('all')"),
    'fault': FAULT,
}, checks=[lambda e: None if any(e[k] is not None for k, _, _ in KEYS) else
           'an entry needs at least one of ' + ', '.join(k for k, _, _ in KEYS)]),
    min_len=1)})


class ScheduleError(SceneError):
    """A schedule file is invalid, or asks what its scene cannot do; one line per problem,
    each naming the key (``schedule[2].speed``) and the allowed range."""

    def __init__(self, errors: str | Iterable[str], source: str | None = None) -> None:
        errors = [e.replace("scene key '", "key '", 1) for e in
                  ((errors,) if isinstance(errors, str) else errors)]
        super().__init__(errors, source)
        if source is not None and len(self.errors) > 1:
            self.args = ('\n'.join([f'invalid schedule {source} ({len(self.errors)} errors):',
                                    *self.errors]),)


@dataclasses.dataclass(frozen=True)
class Entry:
    """One schedule entry: its time and what it sets (the keys given, in :data:`KEYS` order).

    Attributes
    ----------
    at : float
        Sim time (s).
    commands : tuple of (str, str, str, object)
        Schedule key, ``'topic'`` or ``'parameter'``, the node's name for it, and the value
        (SI: rad/s, rad/s^2, m/s^2; bool; int; a ``fault``'s plain SI mapping,
        :meth:`~.fault_spec.FaultSpec.as_dict`; a ``clear_fault``'s name or ``'all'``).
    """

    at: float
    commands: tuple[tuple[str, str, str, Any], ...]


class Schedule:
    """A loaded schedule, played forward in sim time.

    Parameters
    ----------
    entries : sequence of Entry
        Applied in time order (equal times in the file's order).
    source : str
        Where it came from (the file), for messages.
    text : str
        The file's text, kept for the log's metadata.
    """

    def __init__(self, entries: Iterable[Entry], source: str = '<schedule>',
                 text: str = '') -> None:
        self.entries = sorted(entries, key=lambda e: e.at)   # stable: file order at one time
        self.source = source
        self.text = text
        self._next = 0

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Schedule:
        """Read and check a schedule file (YAML).

        Parameters
        ----------
        path : str or os.PathLike
            The file.

        Raises
        ------
        ScheduleError
            Every problem, each naming its key and allowed range (a :class:`SceneError`:
            a missing file or bad YAML is reported as for a scene).
        """
        import pathlib

        from ..scene.loading import load_yaml
        file = os.fspath(path)
        raw = load_yaml(pathlib.Path(file), source=file, kind='schedule')
        try:
            value = validate(SCHEMA, raw, source=file)
        except SceneError as exc:
            raise ScheduleError(exc.errors, source=file) from None

        entries = [Entry(e['at'], tuple((key, kind, name, e[key]) for key, kind, name in KEYS
                                        if e[key] is not None))
                   for e in value['schedule']]
        with open(file, encoding='utf-8') as f:
            text = f.read()
        return cls(entries, source=file, text=text)

    def __len__(self) -> int:
        return len(self.entries)

    @property
    def done(self) -> bool:
        """bool: Every entry has been applied."""
        return self._next >= len(self.entries)

    def check(self, live: LiveSimulation) -> None:
        """Refuse, before a run, entries the simulation ``live`` cannot take.

        Raises
        ------
        ScheduleError
            Naming the entry, the key and the reason (a speed above ``max_speed``, a speed
            or rate for a scene without a commanded rotor, an unbalance without one, dampers
            on without impactors, an unbalance above ``max_unbalance``; a fault on an
            accelerometer the scene does not have, naming the ones it has, a fault whose
            window has passed at ``at`` or that cannot apply, a fault name given twice, a
            ``clear_fault`` of a name no earlier entry gives).
        """
        problems: list[str] = []
        commanded = live.speed_commanded
        problems += self._check_faults(live)
        for i, entry in enumerate(self.entries):
            for key, _, _name, value in entry.commands:
                where = f'schedule[{i}].{key} (at {entry.at:g} s)'
                if key in ('speed', 'speed_rate') and not commanded:
                    problems.append(f'{where}: scene {live.scene.name!r} has no commanded rotor')
                elif key == 'speed' and value > live.max_speed:
                    problems.append(f'{where}: {value:g} rad/s is above max_speed '
                                    f'{live.max_speed:g} rad/s')
                elif key == 'unbalance' and live.unbalance is None:
                    problems.append(f'{where}: scene {live.scene.name!r} has no rotor unbalance')
                elif key == 'unbalance' and value > live.max_unbalance:
                    problems.append(f'{where}: {value:g} is above max_unbalance '
                                    f'{live.max_unbalance:g}')
                elif key == 'dampers' and value and not live.scene.impactors:
                    problems.append(f'{where}: scene {live.scene.name!r} has no impactors')
        if problems:
            raise ScheduleError(problems, source=self.source)

    def _check_faults(self, live: LiveSimulation) -> list[str]:
        """The problems of the fault entries against ``live``'s accelerometers: each added,
        in order, to an injector of the same channels at its entry's time (list of str)."""
        import re

        from .fault_kinds import after_index
        from .faults import FaultInjector
        names = [acc.name for acc in live.accelerometers]
        dry = FaultInjector.for_channels(live.channels, live.sample_rate, seed=0)
        problems: list[str] = []
        given: list[str] = []
        for i, entry in enumerate(self.entries):
            at = self.boundary(entry, live.sample_rate)
            for key, _, _, value in entry.commands:
                where = f'schedule[{i}].{key}'
                if key == 'clear_fault':
                    if value != 'all' and value not in given:
                        known = ', '.join(given) or 'none'
                        problems.append(f'{where} (at {entry.at:g} s): no earlier entry adds a '
                                        f'fault named {value!r}; the faults: {known}')
                    continue
                if key != 'fault':
                    continue
                problem = accelerometer_problem(value['accelerometer'], names)
                if problem:
                    problems.append(f'{where}.accelerometer (at {entry.at:g} s): {problem}')
                    continue
                onset = at if value['onset'] is None else value['onset']
                end = None if value['duration'] is None else onset + value['duration']
                if end is not None and (after_index(end, live.sample_rate)
                                        <= after_index(at, live.sample_rate)):
                    problems.append(f"{where}.onset (at {entry.at:g} s): the window "
                                    f"{onset:g} s + {value['duration']:g} s has passed "
                                    'when the entry applies')
                    continue
                try:
                    given.append(dry.add(value, now=at, key=where))
                except FaultError as exc:   # a name in use, an intermittent without a rail
                    for line in exc.errors:
                        match = re.match(r"key '([^']*)': (.*)", line, re.S)
                        problems.append(f'{match.group(1)} (at {entry.at:g} s): '
                                        f'{match.group(2)}' if match else line)
        return problems

    def boundary(self, entry: Entry, sample_rate: float) -> float:
        """The sim time (s) ``entry`` applies at: its time rounded up to a sample boundary.

        Parameters
        ----------
        entry : Entry
        sample_rate : float
            Output sample rate (Hz).
        """
        return math.ceil(entry.at * sample_rate - 1e-6) / sample_rate

    def due(self, t: float, sample_rate: float) -> list[Entry]:
        """Entries due at sim time ``t`` (s) and not applied yet; they count as applied.

        Parameters
        ----------
        t : float
            Sim time now (s), a sample boundary.
        sample_rate : float
            Output sample rate (Hz).
        """
        out: list[Entry] = []
        half = 0.5 / sample_rate
        while not self.done and self.boundary(self.entries[self._next], sample_rate) < t + half:
            out.append(self.entries[self._next])
            self._next += 1
        return out

    def samples_to_next(self, t: float, sample_rate: float) -> int | None:

        """Output samples from sim time ``t`` (s) to the next entry's boundary (None if
        none is left): a driver steps no further before applying it."""
        if self.done:
            return None
        at = self.boundary(self.entries[self._next], sample_rate)
        return max(0, int(round((at - t) * sample_rate)))


__all__ = ['Entry', 'KEYS', 'SCHEMA', 'Schedule', 'ScheduleError']
