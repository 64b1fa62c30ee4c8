"""Grid sweeps of scene keys with worst-case responses (paper Tables 4.3.1, 4.3.2).

Every combination of the grid values (``--grid impactors.0.mass=1,2,3 --grid
'impactors.0.clearance=1 mil,2 mil'``) is run once with impactors; every combination of the
grid keys that are not impactor keys is also run once without impactors (``impactors=[]``)
as the reference. Per point and per *phase* (a time window of the run) the worst case over
the sensors of the peak displacement and of the peak mean acceleration (impacts included) is
reported, with reduction ratios reference / with-impactors (> 1: the damper helps), as the
paper's "Reduct" columns.

A ``*`` in place of a list index sets the key in every element of that list at once:
``--grid 'impactors.*.clearance=0.5 mil,0.85 mil'`` gives all twelve hpotp impactors the same
clearance per point (``impactors.0.clearance`` moves one of them only).

Phases default to ``run`` (the whole run, start-up transient included) and ``steady`` (the
trailing ``simulation.window``). A scene with a speed ramp adds its own, e.g.
``criticals=0:5`` and ``full_speed=5:6`` (s), without changing the tasks.
"""
from __future__ import annotations

import itertools
import re
import time

from .frf import failure, point_record
from .runner import Point, point_seed, run_points

OBJECTIVES = ('acceleration', 'displacement')
WILDCARD = '*'
_KEY_TOKEN_RE = re.compile(r'[^.\[\]]+')
DEFAULT_PHASES = (('run', 0.0, None), ('steady', None, None))


def split_values(text):
    """Split ``'1 mil,2 mil,[1, 2]'`` at top-level commas (brackets and quotes kept)."""
    out, depth, quote, cur = [], 0, None, ''
    for ch in text:
        if quote:
            quote = None if ch == quote else quote
        elif ch in '\'"':
            quote = ch
        elif ch in '[{':
            depth += 1
        elif ch in ']}':
            depth -= 1
        elif ch == ',' and depth == 0:
            out.append(cur.strip())
            cur = ''
            continue
        cur += ch
    out.append(cur.strip())
    return [v for v in out if v != '']


def is_impactor_key(key):
    """bool: ``key`` is inside the ``impactors`` list (meaningless without impactors)."""
    return key.split('.', 1)[0].split('[', 1)[0] == 'impactors'


def has_wildcard(key):
    """bool: ``key`` has a ``*`` list index (``impactors.*.clearance``, ``impactors[*].cor``)."""
    return WILDCARD in _KEY_TOKEN_RE.findall(key)


def expand_key(key, scene_dict, option='--grid'):
    """The concrete keys a wildcard key stands for in one scene.

    Parameters
    ----------
    key : str
        Dotted scene key; a ``*`` token stands for every index of the list at that place.
    scene_dict : dict
        A validated scene (its lists say how many elements each wildcard covers).
    option : str
        The command-line option that gave ``key``, named in the error.

    Returns
    -------
    list of str
        ``[key]`` without a wildcard, otherwise one dotted key per list element
        (``impactors.0.clearance``, ``impactors.1.clearance``, ...).

    Raises
    ------
    ValueError
        One line naming ``key`` when a wildcard matches nothing (an empty list, or a place
        in the scene that is not a list).
    """
    tokens = _KEY_TOKEN_RE.findall(key)
    if WILDCARD not in tokens:
        return [key]
    paths = [([], scene_dict)]
    for i, token in enumerate(tokens):
        nxt = []
        for prefix, node in paths:
            if token == WILDCARD:
                if not isinstance(node, list) or not node:
                    where = '.'.join(tokens[:i]) or 'the scene'
                    what = 'an empty list' if isinstance(node, list) else 'not a list'
                    raise ValueError(f"{option} {key}: '*' matches nothing ({where} is {what} "
                                     'in this scene)')
                nxt += [(prefix + [str(k)], item) for k, item in enumerate(node)]
            elif isinstance(node, dict):
                nxt.append((prefix + [token], node.get(token)))
            elif isinstance(node, list) and token.isdigit() and int(token) < len(node):
                nxt.append((prefix + [token], node[int(token)]))
            else:   # a key past the wildcard that the scene lacks: validation names it
                nxt.append((prefix + [token], None))
        paths = nxt
    return ['.'.join(prefix) for prefix, _ in paths]


def lookup_key(scene_dict, key):
    """The SI value at ``key``; for a wildcard key the common value (a list if they differ)."""
    from .measure import lookup
    values = [lookup(scene_dict, k) for k in expand_key(key, scene_dict)]
    return values[0] if all(v == values[0] for v in values) else values


def key_overrides(key, value, expansions):
    """``key=value`` override lines, one per concrete key of a wildcard ``key``."""
    return [f'{k}={value}' for k in expansions.get(key, [key])]


def peaks(point):
    """Task: worst-case responses of one run, per phase.

    Parameters
    ----------
    point : Point
        ``params``: ``phases``, a list of ``(name, t0, t1)`` (s; ``t0`` None = the start of
        the trailing ``simulation.window``, ``t1`` None = the end of the run), and
        ``keys``, scene keys whose validated (SI) values are reported.

    Returns
    -------
    dict
        ``phases``: per phase, per sensor ``peak_displacement_m`` (refined peak ``|x|``),
        ``peak_acceleration_m_s2`` (largest mean acceleration per sample period, impacts
        included, through the sensor's ``lowpass`` if it has one) and
        ``rms_displacement_m``; the worst case over the sensors (``worst_displacement_m``,
        ``worst_acceleration_m_s2``, with the sensor names) and
        ``impacts_per_second`` per impactor. ``resolved``: the ``keys``' SI values. With
        ``params['divergence_is_result']`` (the no-impactor references), a run that diverges
        returns ``phases`` None, ``diverged_at_s`` (s) and ``divergence`` (what).
    """
    import numpy as np

    from ..integrate.divergence import Divergence
    from ..live.filters import scene_lowpass
    from .analysis import refined_peak
    from .measure import load_point, start, window_impact_rates
    scene = load_point(point)
    cfg = scene.scene['simulation']
    sim = start(scene)
    lowpass = scene_lowpass(scene, sim.dt)   # checks the cutoffs before the run
    v0 = sim.integrator.model.sensors @ sim.integrator.state()[1]
    try:
        samples = sim.advance_to(cfg['duration'])
    except Divergence as exc:
        if not point.params.get('divergence_is_result'):
            raise
        # a reference without impactors that grows without bound (a linearly unstable
        # structure) is a result: the reduction the impactors give is unbounded
        return {'phases': None, 'diverged_at_s': exc.t, 'divergence': exc.what,
                'resolved': {k: lookup_key(scene.scene, k) for k in point.params.get('keys', ())}}
    acc = lowpass.apply(sim.mean_acceleration(samples, v0))
    events = sim.take_events()
    t, x = samples.t, samples.displacement
    names = sim.sensor_names
    out = {}
    for name, t0, t1 in point.params.get('phases', DEFAULT_PHASES):
        t0 = sim.t - cfg['window'] if t0 is None else float(t0)
        t1 = sim.t if t1 is None else float(t1)
        sel = (t > t0) & (t <= t1)
        sensors = {s: {'peak_displacement_m': refined_peak(x[sel, k]),
                       'peak_acceleration_m_s2': float(np.max(np.abs(acc[sel, k])))
                       if sel.any() else 0.0,
                       'rms_displacement_m': float(np.sqrt(np.mean(x[sel, k] ** 2)))
                       if sel.any() else 0.0}
                   for k, s in enumerate(names)}
        phase = {'t0_s': t0, 't1_s': t1, 'sensors': sensors}
        for what, unit in (('displacement', 'm'), ('acceleration', 'm_s2')):
            field = f'peak_{what}_{unit}'
            worst = max(names, key=lambda s: sensors[s][field]) if names else None
            phase[f'worst_{what}_{unit}'] = sensors[worst][field] if worst else 0.0
            phase[f'worst_{what}_sensor'] = worst
        phase['impacts_per_second'] = window_impact_rates(events, sim.impactor_names, t0, t1)
        out[name] = phase
    resolved = {k: lookup_key(scene.scene, k) for k in point.params.get('keys', ())}
    return {'phases': out, 'resolved': resolved}


def make_points(scene, grid, overrides=(), *, phases=DEFAULT_PHASES, has_impactors=True,
                seed=0, expansions=None):
    """Points of a grid sweep and of its no-impactor references.

    Parameters
    ----------
    scene : str
        Scene name or path.
    grid : sequence of (str, sequence of str)
        Scene keys and their values (as override text: units allowed).
    overrides : sequence of str
        Base overrides (applied first).
    phases : sequence of (str, float or None, float or None)
        See :func:`peaks`.
    has_impactors : bool
        False: the scene has no impactors, so no reference runs are added.
    seed : int
        Study seed.
    expansions : dict of str to list of str, optional
        Concrete keys per wildcard grid key (see :func:`expand_key`); each point sets all.

    Returns
    -------
    list of Point
        Grid points (``labels['reference']`` False) then references (True).
    """
    keys = [k for k, _ in grid]
    expansions = expansions or {}
    params = {'phases': [tuple(p) for p in phases], 'keys': keys}
    points, refs = [], {}
    for combo in itertools.product(*[list(v) for _, v in grid]):
        values = dict(zip(keys, combo))
        ov = list(overrides) + [line for k, v in values.items()
                                for line in key_overrides(k, v, expansions)]
        points.append(Point(peaks, scene, tuple(ov), point_seed(seed, '\n'.join([scene] + ov)),
                            params, {'grid': values, 'reference': False}))
        if has_impactors:
            ref = {k: v for k, v in values.items() if not is_impactor_key(k)}
            refs.setdefault(tuple(ref.items()), ref)
    for ref in refs.values():
        ov = list(overrides) + [f'{k}={v}' for k, v in ref.items()] + ['impactors=[]']
        ref_params = dict(params, keys=list(ref), divergence_is_result=True)
        points.append(Point(peaks, scene, tuple(ov), point_seed(seed, '\n'.join([scene] + ov)),
                            ref_params, {'grid': ref, 'reference': True}))
    return points


def sweep(scene, grid, overrides=(), *, phases=DEFAULT_PHASES, best_over=None,
          objective='acceleration', seed=0, executor='process', workers=None,
          dask_address=None, progress=None):
    """Run a grid sweep.

    Parameters
    ----------
    scene : str
        Scene name or path.
    grid : sequence of (str, sequence of str)
        Scene keys and their values; a ``*`` list index sets every element
        (``impactors.*.clearance``, see :func:`expand_key`).
    overrides : sequence of str
        Base overrides.
    phases : sequence of (str, float or None, float or None)
        Time windows, see :func:`peaks`.
    best_over : str, optional
        Grid key to optimize per combination of the other keys (default: the first grid
        key containing ``clearance``, if any): the best value minimizes the worst case,
        over the phases, of ``objective``.
    objective : {'acceleration', 'displacement'}
        What "best" minimizes.
    seed, executor, workers, dask_address, progress
        See :func:`.runner.run_points`.

    Returns
    -------
    dict
        ``study``, ``scene``, ``grid``, ``phases``, ``rows`` (per grid point: the grid
        values as given and in SI (``<key>_si``), then per phase worst displacement (m),
        worst acceleration (m/s^2 and g), reductions and impacts per second), ``best``,
        ``points``, ``failures`` and ``wall_time_s``.
    """
    from ..scene.build import load
    if objective not in OBJECTIVES:
        raise ValueError(f"objective must be one of {', '.join(OBJECTIVES)}, got {objective!r}")
    grid = [(k, list(v)) for k, v in grid]
    if not grid:
        raise ValueError('give at least one --grid KEY=V1,V2,...')
    keys = [k for k, _ in grid]
    if best_over is None:
        best_over = next((k for k in keys if 'clearance' in k), None)
    elif best_over not in keys:
        raise ValueError(f'--best-over {best_over!r} is not a grid key ({", ".join(keys)})')
    names = [p[0] for p in phases]
    if len(set(names)) != len(names):
        raise ValueError(f'phase names must differ, got {names}')
    base = load(scene, list(overrides))
    from .measure import check_memory
    check_memory(base)
    expansions = {k: expand_key(k, base.scene) for k in keys if has_wildcard(k)}
    points = make_points(scene, grid, overrides, phases=phases,
                         has_impactors=bool(base.scene['impactors']), seed=seed,
                         expansions=expansions)
    start = time.perf_counter()
    results = run_points(points, executor, workers=workers, dask_address=dask_address,
                         progress=progress)
    wall = time.perf_counter() - start
    rows = tabulate(results, keys, names)
    return {'study': 'sweep', 'scene': base.name, 'source': base.source,
            'overrides': list(overrides), 'grid': [{'key': k, 'values': v} for k, v in grid],
            'phases': [{'name': n, 't0_s': a, 't1_s': b} for n, a, b in phases],
            'objective': objective, 'best_over': best_over, 'rows': rows,
            'best': best(rows, keys, names, best_over, objective),
            'points': [point_record(r) for r in results],
            'failures': [failure(r) for r in results if not r.ok], 'wall_time_s': wall}


def tabulate(results, keys, phase_names):
    """One flat row per grid point (see :func:`sweep`)."""
    from .analysis import G0
    refs = {tuple(sorted(r.point.labels['grid'].items())): r for r in results
            if r.point.labels['reference']}
    rows = []
    for r in results:
        if r.point.labels['reference']:
            continue
        grid = r.point.labels['grid']
        row = dict(grid)
        for k in keys:
            row[f'{k}_si'] = r.value['resolved'].get(k) if r.ok else None
        ref = refs.get(tuple(sorted((k, v) for k, v in grid.items() if not is_impactor_key(k))))
        ref_ok = ref is not None and ref.ok
        row['without_diverged_at_s'] = ref.value.get('diverged_at_s') if ref_ok else None
        for name in phase_names:
            ph = r.value['phases'][name] if r.ok else None
            rph = ref.value['phases'][name] if ref_ok and ref.value['phases'] else None
            for what, unit in (('displacement', 'm'), ('acceleration', 'm_s2')):
                col = f'worst_{what}_{unit}'
                val = ph[col] if ph else None
                row[f'{name}_{col}'] = val
                if what == 'acceleration':
                    row[f'{name}_worst_acceleration_g'] = None if val is None else val / G0
                without = rph[col] if rph else None
                row[f'{name}_without_{what}_{unit}'] = without
                row[f'{name}_{what}_reduction'] = (without / val if val and without is not None
                                                   else None)
            row[f'{name}_impacts_per_second'] = (sum(ph['impacts_per_second'].values())
                                                 if ph else None)
        row['error'] = r.error
        rows.append(row)
    return rows


def best(rows, keys, phase_names, best_over, objective):
    """Best ``best_over`` value per combination of the other grid keys.

    Returns
    -------
    list of dict
        The other keys' values, ``best_over``'s best value and the worst case over the phases
        of the objective there (m or m/s^2); empty without ``best_over``.
    """
    if best_over is None:
        return []
    unit = 'm' if objective == 'displacement' else 'm_s2'
    others = [k for k in keys if k != best_over]
    groups = {}
    for row in rows:
        vals = [row[f'{n}_worst_{objective}_{unit}'] for n in phase_names]
        if any(v is None for v in vals):
            continue
        groups.setdefault(tuple(row[k] for k in others), []).append((max(vals), row[best_over]))
    out = []
    for group, cands in groups.items():
        worst, value = min(cands, key=lambda c: c[0])
        out.append({**dict(zip(others, group)), best_over: value,
                    f'worst_{objective}_{unit}': worst})
    return out


#: Per phase: line style, marker, marker face (None: filled) and size (points), so that the
#: run and steady lines stay visible where they coincide (open squares around filled dots).
PHASE_STYLES = (('-', 'o', None, 4.5), ('--', 's', 'none', 8.0), (':', '^', 'none', 10.0))
#: Line styles of the no-impactor reference levels, per phase.
REFERENCE_STYLES = ((0, (6, 2)), (0, (2, 2)), (0, (6, 2, 1, 2)))


def plot(result, path):
    """Plot the objective's worst case versus the best-over key (or the point index).

    One colour per combination of the other grid keys, one line style and marker per phase
    (open markers on the later phases, so coinciding phases both show), and per phase the
    level without impactors as a labelled horizontal grey line.

    Parameters
    ----------
    result : dict
        Output of :func:`sweep`.
    path : str or os.PathLike
        PNG file (Agg backend).
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    from .analysis import G0
    from .display import axis_unit
    obj = result['objective']
    # the table's units: displacement in m, acceleration in g
    field, ylabel = (('m', 'm') if obj == 'displacement' else ('g', 'g'))
    to_unit = 1.0 if obj == 'displacement' else 1.0 / G0
    without_field = 'm' if obj == 'displacement' else 'm_s2'
    keys = [g['key'] for g in result['grid']]
    xkey = result['best_over'] or keys[0]
    others = [k for k in keys if k != xkey]
    given = next(g['values'] for g in result['grid'] if g['key'] == xkey)
    xunit, xfactor = axis_unit(xkey, given)
    phases = [p['name'] for p in result['phases']]
    fig, ax = plt.subplots(figsize=(7, 4.5), dpi=120)
    groups = {}
    for row in result['rows']:
        groups.setdefault(tuple(row[k] for k in others), []).append(row)
    numeric, references, xs_all = True, {}, []
    for g, (group, rows) in enumerate(groups.items()):
        xs = [row[f'{xkey}_si'] for row in rows]
        if any(x is None or not isinstance(x, (int, float)) for x in xs):
            xs, numeric = list(range(len(rows))), False
        else:
            xs = [x / xfactor for x in xs]
        xs_all += xs
        label = ', '.join(f'{k}={v}' for k, v in zip(others, group)) or 'with impactors'
        for k, phase in enumerate(phases):
            line, marker, face, size = PHASE_STYLES[k % len(PHASE_STYLES)]
            ys = [row[f'{phase}_worst_{obj}_{field}'] for row in rows]
            # one colour per group, one line style and marker per phase
            ax.plot(xs, [float('nan') if y is None else y for y in ys], linestyle=line,
                    marker=marker, ms=size, mfc=face, mew=1.2, color=f'C{g % 10}',
                    label=f'{label} ({phase})', zorder=3 + len(phases) - k)
            # the level without impactors depends only on the non-impactor keys
            ref_group = tuple(f'{o}={v}' for o, v in zip(others, group)
                              if not is_impactor_key(o))
            for row in rows:
                level = row.get(f'{phase}_without_{obj}_{without_field}')
                if level is not None:
                    references[(ref_group, k)] = level * to_unit
    if references and xs_all:
        lo, hi = min(xs_all), max(xs_all)
        for (ref_group, k), level in references.items():
            where = f", {', '.join(ref_group)}" if ref_group else ''
            ax.plot([lo, hi], [level, level], color='0.35', lw=1.3,
                    linestyle=REFERENCE_STYLES[k % len(REFERENCE_STYLES)], zorder=2,
                    label=f'without impactors ({phases[k]}{where})')
    ax.set_xlabel(f'{xkey} ({xunit})' if numeric and xunit else
                  xkey if numeric else f'{xkey} (point index)')
    ax.set_ylabel(f'worst {obj} over the sensors ({ylabel})')
    ax.set_title(f"sweep: {result['scene']}")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
