"""A ``study dataset`` spec read and checked: the plan of its runs, each with its id.

The spec's keys are in :mod:`.dataset`'s docstring. A run's id is a digest of everything
that decides its log's bytes, so a run whose inputs are unchanged keeps its id.
"""
from __future__ import annotations

import hashlib
import itertools
import json
import math
import os

from ..scene.schema import SceneError
from .dataset_manifest import file_sha256

#: the keys a spec may have (any other is refused, naming these)
SPEC_KEYS = ('scene', 'duration', 'noise_std', 'tick_period', 'truth', 'faults', 'overrides',
             'grid', 'schedules', 'seeds', 'sample')


class DatasetError(SceneError):
    """A data set spec is invalid; one line per problem, each naming its key."""

    def __init__(self, errors, source=None):
        super().__init__(errors, source)
        if source is not None and len(self.errors) > 1:
            self.args = ('\n'.join([f'invalid data set spec {source} ({len(self.errors)} '
                                    'errors):', *self.errors]),)


def _value_text(value):
    """A spec value as the text of a ``key=value`` override."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return repr(value)
    return str(value)


def load_spec(path):
    """Read and check a data set spec; return the plan of its runs.

    Parameters
    ----------
    path : str or os.PathLike
        The spec (YAML).

    Returns
    -------
    list of dict
        One per run, in spec order: ``id``, ``scene``, ``overrides`` (the fixed ones, then
        the run's), ``keys`` (the run's own scene keys and values, as written), ``schedule``
        (absolute path or None), ``seed``, ``noise_std`` (m/s^2), ``duration`` (s),
        ``tick_period`` (s), ``truth`` (bool), ``faults`` (the sensor faults of every run,
        plain SI mappings; empty when none) and ``inputs_sha256`` (the digest of the inputs
        the id is made of).

    Raises
    ------
    DatasetError
        Every problem of the spec, each naming its key; a missing schedule file.
    """
    import pathlib

    import numpy as np

    import impact_damper_sim

    from ..recording.node_topics import TICK_PERIOD
    from ..scene.loading import load_yaml
    from ..scene.units import UnitError, parse_quantity
    from .tick_period import parse_tick_period
    path = os.fspath(path)
    raw = load_yaml(pathlib.Path(path), source=path)
    base = os.path.dirname(os.path.abspath(path))
    errors = []
    for key in raw:
        if key not in SPEC_KEYS:
            errors.append(f"key '{key}': unknown; expected one of {', '.join(SPEC_KEYS)}")

    def quantity(key, dimension, default=None, low=0.0, positive=False):
        value = raw.get(key, default)
        if value is None:
            errors.append(f"key '{key}': missing; expected a {dimension}")
            return None
        try:
            si = parse_quantity(value, dimension, key=key)
        except UnitError as exc:
            errors.append(f"key '{key}': {exc}")
            return None
        if si < low or (positive and si <= 0):
            errors.append(f"key '{key}': {value} must be {'>' if positive else '>='} {low:g}")
            return None
        return si

    def text_list(key, value):
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            errors.append(f"key '{key}': expected a list of strings, got {value!r}")
            return []
        return list(value)

    def schedule_files(key, value):
        files = []
        for i, name in enumerate(text_list(key, value)):
            full = os.path.join(base, name)
            if not os.path.isfile(full):
                errors.append(f"key '{key}[{i}]': schedule file {full} does not exist")
            files.append(full)
        return files

    scene = raw.get('scene')
    if not isinstance(scene, str) or not scene:
        errors.append("key 'scene': expected a scene name or file")
    elif scene.endswith(('.yaml', '.yml')) and not os.path.isabs(scene):
        scene = os.path.join(base, scene)   # a scene file next to the spec
    duration = quantity('duration', 'time', positive=True)
    noise_std = quantity('noise_std', 'acceleration', default=0.0)
    tick_period = None
    try:
        tick_period = parse_tick_period(raw.get('tick_period', TICK_PERIOD), "key 'tick_period'")
    except SceneError as exc:
        errors.append(str(exc))
    truth = raw.get('truth', False)
    if not isinstance(truth, bool):
        errors.append(f"key 'truth': expected true or false, got {truth!r}")
        truth = False
    faults = []
    if raw.get('faults') is not None:   # the accelerometers are checked when a run starts
        from ..live.fault_spec import parse_faults
        try:
            faults = [{k: v for k, v in spec.as_dict().items() if v is not None}
                      for spec in parse_faults(raw['faults'])]
        except SceneError as exc:
            errors += list(exc.errors)
    fixed = text_list('overrides', raw.get('overrides', []))
    runs = []   # (keys dict, schedule, seed)
    if 'sample' in raw:
        if any(k in raw for k in ('grid', 'schedules', 'seeds')):
            errors.append("key 'sample': give either sample or grid/schedules/seeds")
        sample = raw['sample'] if isinstance(raw['sample'], dict) else {}
        if not isinstance(raw['sample'], dict):
            errors.append("key 'sample': expected a mapping with n, seed, keys")
        n, seed = sample.get('n'), sample.get('seed', 0)
        if not (isinstance(n, int) and not isinstance(n, bool) and 1 <= n <= 1_000_000):
            errors.append(f"key 'sample.n': expected an integer in [1, 1000000], got {n!r}")
            n = 0
        if not (isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0):
            errors.append(f"key 'sample.seed': expected an integer >= 0, got {seed!r}")
            seed = 0
        keys = sample.get('keys', {})
        if not isinstance(keys, dict) or not keys:
            errors.append("key 'sample.keys': expected a mapping of scene keys to ranges or "
                          'lists')
            keys = {}
        draws = {}
        for key, spec in keys.items():
            where = f"key 'sample.keys.{key}'"
            if isinstance(spec, list) and spec:
                draws[key] = ('choice', spec)
            elif isinstance(spec, dict) and set(spec) <= {'low', 'high', 'unit'} and all(
                    isinstance(spec.get(b), (int, float)) and not isinstance(spec.get(b), bool)
                    and math.isfinite(spec.get(b)) for b in ('low', 'high')) \
                    and spec['low'] <= spec['high']:
                draws[key] = ('uniform', spec)
            else:
                errors.append(f'{where}: expected a non-empty list, or {{low, high, unit}} '
                              f'with finite low <= high, got {spec!r}')
        schedules = schedule_files('sample.schedules', sample.get('schedules', []))
        rng = np.random.default_rng(seed)
        for _ in range(n):
            values = {}
            for key, (kind, spec) in draws.items():
                if kind == 'choice':
                    values[key] = spec[int(rng.integers(len(spec)))]
                else:
                    x = float(spec['low'] + (spec['high'] - spec['low']) * rng.random())
                    values[key] = f"{x!r} {spec['unit']}" if spec.get('unit') else x
            chosen = schedules[int(rng.integers(len(schedules)))] if schedules else None
            runs.append((values, chosen, int(rng.integers(2**31 - 1))))
    else:
        grid = raw.get('grid', {})
        if not isinstance(grid, dict) or not all(
                isinstance(v, list) and v and all(isinstance(x, (str, int, float, bool))
                                                  for x in v) for v in grid.values()):
            errors.append("key 'grid': expected a mapping of scene keys to non-empty lists of "
                          f'values, got {grid!r}')
            grid = {}
        schedules = schedule_files('schedules', raw.get('schedules', [])) or [None]
        seeds = raw.get('seeds', [0])
        if not (isinstance(seeds, list) and seeds and all(
                isinstance(s, int) and not isinstance(s, bool) and 0 <= s <= 2**31 - 1
                for s in seeds)):
            errors.append(f"key 'seeds': expected a list of integers in [0, 2147483647], "
                          f'got {seeds!r}')
            seeds = [0]
        for combo in itertools.product(*grid.values()):
            for schedule in schedules:
                for seed in seeds:
                    runs.append((dict(zip(grid, combo)), schedule, seed))
    if errors:
        raise DatasetError(errors, source=path)
    version = impact_damper_sim.__version__
    plan = []
    for keys, schedule, seed in runs:
        overrides = fixed + [f'{k}={_value_text(v)}' for k, v in keys.items()]
        schedule_sha = file_sha256(schedule) if schedule else None
        inputs = {'scene': scene, 'scene_sha256': (file_sha256(scene) if os.path.isfile(scene)
                                                   else None),
                  'overrides': overrides, 'schedule_sha256': schedule_sha, 'seed': seed,
                  'noise_std': noise_std, 'duration': duration, 'tick_period': tick_period,
                  'software_version': version}
        if truth:   # only when on: the ids of runs without it stay what they were
            inputs['truth'] = True
        if faults:   # likewise
            inputs['faults'] = faults
        digest = hashlib.sha256(json.dumps(inputs, sort_keys=True).encode()).hexdigest()
        plan.append({'id': 'r' + digest[:12], 'scene': scene, 'overrides': overrides,
                     'keys': keys, 'schedule': schedule, 'seed': seed, 'noise_std': noise_std,
                     'duration': duration, 'tick_period': tick_period, 'truth': truth,
                     'faults': faults, 'inputs_sha256': digest})
    ids = [run['id'] for run in plan]
    if len(set(ids)) != len(ids):
        dup = sorted({i for i in ids if ids.count(i) > 1})
        raise DatasetError(f'runs {", ".join(dup)} have the same inputs twice (a repeated '
                           'grid value?)', source=path)
    return plan


__all__ = ['DatasetError', 'SPEC_KEYS', 'load_spec']
