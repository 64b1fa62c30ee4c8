"""Sensor faults as data: the keys of a fault, their units and ranges, and their refusals.

One spec, three sources: a command schedule entry, a node command (a YAML or JSON string on a
command topic or parameter) and a data-set spec. Each is a mapping with engineering units,
checked by the scene schema engine (so a bad value is refused in one line naming the key and
its allowed range, as every scene key is) and converted to SI once::

    {kind: spikes, accelerometer: hpotp_casing, onset: 2 s, duration: 1 s,
     rate: 20 Hz, amplitude: 30 g, width: 2, seed: 7}

Keys of every kind (``onset`` and ``duration`` in sim time):

==================  =====================================================================
``kind``            stuck | dropout | spikes | bias | gain | intermittent
``accelerometer``   the accelerometer's name (its topic suffix ``accel/<name>``)
``name``            to clear it by; default ``<kind>-<n>`` (n counts the faults added)
``onset``           s; none = when the injector gets it (a schedule entry's ``at``, a
                    node command's arrival)
``duration``        s, > 0; none = until cleared
``axes``            the sensor axes it acts on: x, y, z, xy, xz, yz, xyz (default); not
                    for dropout (a sample is missing whole)
==================  =====================================================================

and of each kind:

* ``stuck``: the output holds the last value the channel read before the onset.
* ``dropout``: samples missing (a validity mask; not zeros).
* ``spikes``: random impulses, Poisson in time: ``rate`` (1/s, Hz), ``amplitude``
  (m/s^2, each spike +-amplitude, random sign, the same on every axis it acts on), ``width``
  (output samples, default 1), ``seed``.
* ``bias``: ``step`` (m/s^2) and/or ``drift`` (m/s^2 per s, m/s^3; written ``0.1 g/s``,
  ``5 mg/min``, ``1 m/s^2/h``): bias(t) = step + drift (t - onset).
* ``gain``: ``gain`` (dimensionless, [-1000, 1000]; -1 is a polarity reversal), acting
  before the channel's range and ADC, so a large gain drives them into clipping.
* ``intermittent``: a connection dropping in and out, exponential on and off periods of
  means ``mean_on`` and ``mean_off`` (s), starting with an off period at the onset;
  ``off: rail`` (default) or ``dropout``; ``level`` (m/s^2, rail only) the reading while
  open, before the range/ADC (default: beyond the channel's rail, which clips it); ``seed``.

:func:`parse_fault` reads one mapping (for a schedule's entry, :data:`FAULT` is the same as a
schema field), :func:`parse_faults` a list, :func:`parse_command` a node command's text (a
fault, or ``{clear: <name>}`` / ``{clear: all}``). Accelerometer names are checked when they
are given (a schedule is loaded before its scene: ``FaultSpec.check`` checks them later).
Nothing here imports ROS.
"""
from __future__ import annotations

import dataclasses
import difflib
import re
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, cast

from ..scene.containers import Section
from ..scene.schema import (
    _INVALID,
    Choice,
    Field,
    Integer,
    Quantity,
    SceneError,
    String,
    _Errors,
    _got,
    _interval,
    _join,
    _num,
)
from ..scene.units import UnitError, normalize_unit, unit_factor

#: Fault kinds, in the order their value changes apply within a stage (see :mod:`.faults`).
KINDS = ('gain', 'bias', 'spikes', 'intermittent', 'stuck', 'dropout')
#: Kinds drawing random numbers (they take a ``seed``).
RANDOM_KINDS = ('spikes', 'intermittent')
AXES = ('x', 'y', 'z', 'xy', 'xz', 'yz', 'xyz')
#: Largest seed (a NumPy SeedSequence entropy word).
MAX_SEED = 2 ** 32 - 1
_NAME = r'[A-Za-z][A-Za-z0-9_.-]{0,63}'
_BIG = 1.0e6   # bound of every value (SI): far beyond a test stand, keeps arithmetic finite


class FaultError(SceneError):
    """A fault spec or command is invalid; one line per problem naming the key
    (``fault.rate``, ``schedule[2].fault.rate``) and its allowed range."""

    def __init__(self, errors: str | Iterable[str], source: str | None = None) -> None:
        errors = [e.replace("scene key '", "key '", 1) for e in
                  ((errors,) if isinstance(errors, str) else errors)]
        super().__init__(errors, source)


class _AccelerationRate(Field):
    """A drift rate of an acceleration (SI m/s^3): an acceleration unit over a time unit."""

    def __init__(self, default: object, min: float, max: float, doc: str = '') -> None:
        super().__init__(default, doc)
        self.min, self.max = float(min), float(max)

    def kind(self) -> str:
        return 'acceleration rate'

    def range_text(self) -> str:
        return f'{_interval(self.min, self.max, True, True)} m/s^3'

    def expects(self) -> str:
        return (f'{super().expects()} (units: m/s^3, or an acceleration unit over a time '
                'unit: m/s^2/s, g/s, mg/min, ug/h)')

    def _convert(self, raw: object, path: str, errors: _Errors) -> object:
        try:
            si = _rate_si(raw)
        except UnitError as exc:
            errors.add(path, exc.reason)
            return _INVALID
        if not self.min <= si <= self.max:
            errors.add(path, f'{_num(si)} m/s^3 is out of range {self.range_text()}')
            return _INVALID
        return si


_NUMBER_UNIT = re.compile(r'^\s*([-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$')


def _rate_si(raw: object) -> float:
    """m/s^3 from a number (SI), ``'<number> <acc unit>/<time unit>'`` or {value, unit}."""
    if isinstance(raw, dict) and set(raw) == {'value', 'unit'} and isinstance(raw['unit'], str):
        raw = f"{raw['value']} {raw['unit']}"
    if isinstance(raw, bool) or not isinstance(raw, (int, float, str)):
        raise UnitError(f'expected an acceleration rate, {_got(raw)}')
    if not isinstance(raw, str):
        number, unit = float(raw), ''
    else:
        match = _NUMBER_UNIT.match(raw)
        if re.match(r'\s*[-+]?\.?(nan|inf)', raw, re.IGNORECASE):
            raise UnitError(f'{raw!r} is not a finite number')
        if not match:
            raise UnitError(f"cannot read {raw!r} as an acceleration rate; write e.g. "
                            "'0.1 g/s' or '5 mg/min'")
        number, unit = float(match.group(1)), match.group(2)
    if number != number or number in (float('inf'), float('-inf')):
        raise UnitError(f'{raw!r} is not a finite number')
    canon = normalize_unit(unit) if unit else ''
    if canon in ('', 'm/s^3'):
        return number
    top, slash, bottom = canon.rpartition('/')
    try:
        if not slash:
            raise UnitError('')
        return number * unit_factor(top, 'acceleration') / unit_factor(bottom, 'time')
    except UnitError:
        raise UnitError(f"unknown unit {unit!r} for an acceleration rate; use m/s^3 or an "
                        'acceleration unit over a time unit (m/s^2/s, g/s, mg/min, ug/h)'
                        ) from None


def _common(axes: bool = True) -> dict[str, Field]:
    fields = {
        'kind': Choice(KINDS, doc='what goes wrong'),
        'accelerometer': String(doc="the accelerometer's name (topic accel/<name>)"),
        'name': String(None, pattern=_NAME, doc='to clear it by; default <kind>-<n>'),
        'onset': Quantity('time', None, min=0.0, max=_BIG,
                          doc='sim time it starts; none = when the injector gets it'),
        'duration': Quantity('time', None, min=0.0, max=_BIG, min_inclusive=False,
                             doc='how long it lasts; none = until cleared'),
    }
    if axes:
        fields['axes'] = Choice(AXES, default='xyz', doc='sensor axes it acts on')
    return fields


_SEED = Integer(None, min=0, max=MAX_SEED, doc='seed of its random numbers; none = drawn '
                'from the injector seed and the order faults were added in')


def _bias_given(v: dict[str, Any]) -> str | None:
    if v['step'] == 0.0 and v['drift'] == 0.0:
        return "a bias needs a non-zero 'step' and/or 'drift'"
    return None


def _intermittent_checks(v: dict[str, Any]) -> str | None:
    if v['off'] == 'dropout' and v['axes'] != 'xyz':
        return f"'axes' {v['axes']!r} with off: dropout: a dropout removes whole samples (xyz)"
    if v['off'] == 'dropout' and v['level'] is not None:
        return "'level' applies to off: rail only"
    return None


#: The schema of each kind (the common keys, then the kind's own).
SCHEMAS = {
    'stuck': Section(_common()),
    'dropout': Section(_common(axes=False)),
    'spikes': Section({
        **_common(),
        'rate': Quantity('frequency', min=0.0, max=1.0e5, min_inclusive=False,
                         doc='mean spikes per second (Poisson)'),
        'amplitude': Quantity('acceleration', min=0.0, max=_BIG, min_inclusive=False,
                              doc='height of each spike (random sign)'),
        'width': Integer(1, min=1, max=10000, doc='output samples each spike lasts'),
        'seed': _SEED}),
    'bias': Section({
        **_common(),
        'step': Quantity('acceleration', 0.0, min=-_BIG, max=_BIG, doc='bias step'),
        'drift': _AccelerationRate(0.0, -_BIG, _BIG, doc='bias drift rate from the onset'),
    }, checks=[_bias_given]),
    'gain': Section({
        **_common(),
        'gain': Quantity('dimensionless', min=-1000.0, max=1000.0,
                         doc='multiplies the signal before the range and ADC')}),
    'intermittent': Section({
        **_common(),
        'mean_on': Quantity('time', min=0.0, max=_BIG, min_inclusive=False,
                            doc='mean connected period (exponential)'),
        'mean_off': Quantity('time', min=0.0, max=_BIG, min_inclusive=False,
                             doc='mean open period (exponential)'),
        'off': Choice(('rail', 'dropout'), default='rail',
                      doc='while open: the reading at the rail, or samples missing'),
        'level': Quantity('acceleration', None, min=-_BIG, max=_BIG,
                          doc='reading while open, before the range/ADC; default beyond '
                              "the channel's rail"),
        'seed': _SEED}, checks=[_intermittent_checks]),
}
_COMMON_KEYS = ('kind', 'accelerometer', 'name', 'onset', 'duration', 'axes', 'seed')


@dataclasses.dataclass
class FaultSpec:
    """One sensor fault, SI.

    Attributes
    ----------
    kind : str
        One of :data:`KINDS`.
    accelerometer : str
        The accelerometer's name.
    name : str or None
        None = the injector names it ``<kind>-<n>``.
    onset : float or None
        Sim time it starts (s); None = when added.
    duration : float or None
        How long it lasts (s); None = until cleared.
    axes : str
        Sensor axes it acts on (``'xyz'`` for dropout).
    seed : int or None
        Seed of a random kind (dimensionless); None = from the injector's seed.
    params : dict
        The kind's own values, SI: spikes ``rate`` (1/s), ``amplitude`` (m/s^2), ``width``
        (samples); bias ``step`` (m/s^2), ``drift`` (m/s^3); gain ``gain``
        (dimensionless); intermittent ``mean_on``, ``mean_off`` (s), ``off`` (str),
        ``level`` (m/s^2 or None).
    """

    kind: str
    accelerometer: str
    name: str | None = None
    onset: float | None = None
    duration: float | None = None
    axes: str = 'xyz'
    seed: int | None = None
    params: dict = dataclasses.field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """The spec as a plain SI mapping that :func:`parse_fault` reads back to this spec.

        Returns
        -------
        dict
            ``kind``, ``accelerometer``, ``name``, ``onset`` (s), ``duration`` (s),
            ``axes`` (not for dropout), ``seed`` (random kinds), then the kind's values (SI).
        """
        out = {'kind': self.kind, 'accelerometer': self.accelerometer, 'name': self.name,
               'onset': self.onset, 'duration': self.duration}
        if 'axes' in SCHEMAS[self.kind].fields:
            out['axes'] = self.axes
        if self.kind in RANDOM_KINDS:
            out['seed'] = self.seed
        out.update(self.params)
        return out

    def check(self, accelerometers: Sequence[str], key: str = 'fault') -> None:
        """Refuse an accelerometer that does not exist, naming the ones that do.

        Parameters
        ----------
        accelerometers : sequence of str
            The scene's accelerometer names.
        key : str
            The spec's key in messages.

        Raises
        ------
        FaultError
        """
        problem = accelerometer_problem(self.accelerometer, accelerometers)
        if problem:
            raise FaultError(f"key '{_join(key, 'accelerometer')}': {problem}")


def accelerometer_problem(name: object, accelerometers: Sequence[str]) -> str | None:
    """The refusal of an accelerometer that does not exist, naming the ones that do.

    Parameters
    ----------
    name : str
        The accelerometer asked for.
    accelerometers : sequence of str
        The scene's accelerometer names.

    Returns
    -------
    str or None
        The message without its key; None when ``name`` is one of them.
    """
    names = list(accelerometers)
    if name in names:
        return None
    close = difflib.get_close_matches(str(name), names, n=1, cutoff=0.6)
    hint = f"did you mean {close[0]!r}? " if close else ''
    known = ', '.join(names) if names else 'none'
    return f'{name!r} is not an accelerometer of this scene; {hint}the accelerometers: {known}'


def _convert(raw: object, path: str, errors: _Errors,
             accelerometers: Sequence[str] | None) -> object:
    """A FaultSpec from one raw mapping, or _INVALID after adding its problems."""
    if not isinstance(raw, dict):
        errors.add(path, f"expected a fault mapping (kind, accelerometer, ...); {_got(raw)}")
        return _INVALID
    before = len(errors)
    kind = Choice(KINDS).resolve('kind' in raw, raw.get('kind'), _join(path, 'kind'), errors)
    if len(errors) > before:
        return _INVALID
    value = SCHEMAS[kind].resolve(True, raw, path, errors)
    if accelerometers is not None and isinstance(value['accelerometer'], str):
        problem = accelerometer_problem(value['accelerometer'], accelerometers)
        if problem:   # reported with the other problems, not instead of them
            errors.add(_join(path, 'accelerometer'), problem)
    if len(errors) > before:
        return _INVALID
    if value['name'] == 'all':
        errors.add(_join(path, 'name'), "'all' is reserved ({clear: all} clears every fault)")
        return _INVALID
    return FaultSpec(kind=kind, accelerometer=value['accelerometer'], name=value['name'],
                     onset=value['onset'], duration=value['duration'],
                     axes=value.get('axes', 'xyz'), seed=value.get('seed'),
                     params={k: v for k, v in value.items() if k not in _COMMON_KEYS})


def parse_fault(raw: object, accelerometers: Sequence[str] | None = None, *,
                key: str = 'fault') -> FaultSpec:
    """Read one fault mapping (engineering units allowed) into a :class:`FaultSpec`.

    Parameters
    ----------
    raw : dict
        The mapping (module notes; a plain number is SI).
    accelerometers : sequence of str, optional
        The accelerometer names to check ``accelerometer`` against; None = not checked.
    key : str
        The mapping's key in messages (``'fault'``, ``'schedule[2].fault'``).

    Returns
    -------
    FaultSpec

    Raises
    ------
    FaultError
        Every problem, one line each naming the key and its allowed range.
    """
    errors = _Errors()
    spec = _convert(raw, key, errors, accelerometers)
    if errors:
        raise FaultError(errors.lines())
    return cast(FaultSpec, spec)   # no problem: a FaultSpec, not _INVALID


def parse_faults(raw: object, accelerometers: Sequence[str] | None = None, *,
                 key: str = 'faults') -> list[FaultSpec]:
    """Read a list of fault mappings (a data-set spec's ``faults``); every problem at once.

    Parameters
    ----------
    raw : list of dict
    accelerometers : sequence of str, optional
        As :func:`parse_fault`.
    key : str
        The list's key in messages (items are ``key[i]``).

    Returns
    -------
    list of FaultSpec

    Raises
    ------
    FaultError
        Every problem of every item, one line each.
    """
    errors = _Errors()
    if not isinstance(raw, list):
        errors.add(key, f'expected a list of fault mappings, {_got(raw)}')
        raise FaultError(errors.lines())
    specs = [_convert(r, f'{key}[{i}]', errors, accelerometers) for i, r in enumerate(raw)]
    names = [s.name for s in specs if isinstance(s, FaultSpec) and s.name is not None]
    for name in sorted({n for n in names if names.count(n) > 1}):
        errors.add(key, f'fault name {name!r} is given twice; names must be unique')
    if errors:
        raise FaultError(errors.lines())
    return cast(list[FaultSpec], specs)   # no problem: every item a FaultSpec


@dataclasses.dataclass(frozen=True)
class FaultCommand:
    """A node's fault command: add ``spec``, or clear the fault ``name`` (None = all).

    Attributes
    ----------
    action : str
        ``'add'`` or ``'clear'``.
    spec : FaultSpec or None
        The fault to add (``action == 'add'``).
    name : str or None
        The fault to clear; None = every fault (``action == 'clear'``).
    """

    action: str
    spec: FaultSpec | None = None
    name: str | None = None


def parse_command(text: str | Mapping[str, Any], accelerometers: Sequence[str] | None = None,
                  *, key: str = 'fault') -> FaultCommand:
    """Read a node's fault command: YAML or JSON text (or an already loaded mapping).

    ``{kind: ..., accelerometer: ..., ...}`` adds a fault; ``{clear: <name>}`` clears that
    one and ``{clear: all}`` every fault.

    Parameters
    ----------
    text : str or dict
        The command (a std_msgs/String's data, a parameter's value).
    accelerometers : sequence of str, optional
        As :func:`parse_fault`.
    key : str
        The command's name in messages (the topic or parameter).

    Returns
    -------
    FaultCommand

    Raises
    ------
    FaultError
        Bad YAML (with line and column) or a bad value, in one line naming the key.
    """
    if isinstance(text, str):
        from ..scene.loading import load_yaml
        one_line = '\n' not in text
        try:   # a newline keeps a one-line 'x.yaml' from being read as a file's path
            raw = load_yaml(text + '\n' if one_line and text.strip().endswith(('.yaml', '.yml'))
                            else text, source=key, kind='fault command')
        except SceneError as exc:
            raise FaultError(list(exc.errors)) from None
    else:
        raw = text
    if isinstance(raw, dict) and 'clear' in raw:
        extra = sorted(set(raw) - {'clear'})
        target = raw['clear']
        if extra:
            raise FaultError(f"key '{_join(key, extra[0])}': a clear command has one key, "
                             "'clear'")
        if not isinstance(target, str) or not (target == 'all'
                                               or re.fullmatch(_NAME, target)):
            raise FaultError(f"key '{_join(key, 'clear')}': expected a fault name or 'all', "
                             f'{_got(target)}')
        return FaultCommand('clear', name=None if target == 'all' else target)
    return FaultCommand('add', spec=parse_fault(raw, accelerometers, key=key))


class FaultField(Field):
    """A fault as a schema field (a schedule entry's ``fault`` key): converts to the plain SI
    mapping of :meth:`FaultSpec.as_dict` (schema results are plain trees); the
    accelerometer is checked later, against the scene (:meth:`FaultSpec.check`)."""

    def __init__(self, default: object = None,
                 doc: str = 'a sensor fault (docs: kind, accelerometer, onset, '
                            'duration and the kind\'s keys)') -> None:
        super().__init__(default, doc)

    def kind(self) -> str:
        return 'fault'

    def range_text(self) -> str:
        return ' | '.join(KINDS)

    def _convert(self, raw: object, path: str, errors: _Errors) -> object:
        spec = _convert(raw, path, errors, None)
        return spec.as_dict() if isinstance(spec, FaultSpec) else spec   # else _INVALID


#: A schedule entry's ``fault`` key, optional.
FAULT = FaultField()


__all__ = ['AXES', 'FAULT', 'FaultCommand', 'FaultError', 'FaultField', 'FaultSpec', 'KINDS',
           'MAX_SEED', 'RANDOM_KINDS', 'SCHEMAS', 'accelerometer_problem', 'parse_command',
           'parse_fault', 'parse_faults']
