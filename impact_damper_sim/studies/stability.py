"""Stability maps over cross-coupled stiffness, impactor weight and clearance (paper 4.4).

Each point starts from a small random displacement (``perturbation``, m, at the sensors;
the direction comes from the point's seed) plus whatever forcing the scene has, and runs
``simulation.duration``. The *radial amplitude* is ``r(t) = sqrt(sum_s x_s(t)^2)`` over the
chosen sensors (e.g. the y and z sensors of one node); its RMS over the last
``simulation.window`` is the steady RMS radial amplitude of the paper's Tables 4.4.1/4.4.2.

Criterion: with ``R1``, ``R2`` the RMS radial amplitudes over the last and the previous
window, the point is **unstable** when ``R1/R2 > 1 + growth_tol`` (amplitude still growing),
when ``R1`` is not finite, or when ``R1`` exceeds ``max_amplitude`` if given; otherwise
**stable** (decaying, steady forced response, or a bounded limit cycle, which is how an
impact damper stabilizes a linearly unstable structure). ``ln(R1/R2)/window`` estimates the
growth rate (1/s). A growth slower than ``ln(1 + growth_tol)/window`` is not detected: run
long enough that transients of the stable cases have died out, and compare with the linear
onset (``onset``) for the case without impactors.

``onset`` finds the linear stability limit without impactors: the cross-coupled stiffness at
which the least-damped eigenvalue of the modal model crosses zero, by bisection
(:func:`~impact_damper_sim.modal.stability.onset_cross_coupling`).
"""
from __future__ import annotations

import math
import time

from .frf import failure, point_record
from .runner import Point, point_seed, run_points


def verdict(point):
    """Task: run one point and classify it.

    Parameters
    ----------
    point : Point
        ``params``: ``sensors`` (names for the radial amplitude, None = all),
        ``perturbation`` (m), ``growth_tol`` (dimensionless), ``max_amplitude`` (m or None)
        and ``keys`` (scene keys whose SI values are reported).

    Returns
    -------
    dict
        ``stable`` (bool), ``rms_radial_m`` and ``previous_rms_radial_m`` (m),
        ``growth_ratio`` (R1/R2), ``growth_rate_1_s`` (1/s), ``impacts_per_second`` (1/s,
        last window, all impactors) and per impactor, ``resolved``.
    """
    import numpy as np

    from ..integrate.divergence import Divergence
    from .measure import finite_or_none, load_point, lookup, start, window_impact_rates
    p = point.params
    scene = load_point(point)
    cfg = scene.scene['simulation']
    names = list(scene.model.sensor_names)
    chosen = p.get('sensors') or names
    missing = [s for s in chosen if s not in names]
    if missing:
        raise ValueError(f"unknown sensor(s) {', '.join(missing)} (scene sensors: "
                         f"{', '.join(names) or 'none'})")
    idx = [names.index(s) for s in chosen]
    amp = p.get('perturbation', 0.0)
    q0 = None
    if amp:
        q0 = np.random.default_rng(point.seed).standard_normal(scene.model.n)
        at_sensors = float(np.linalg.norm(scene.model.sensors[idx] @ q0))
        if at_sensors == 0.0:
            raise ValueError('no retained mode moves the chosen sensors; cannot perturb them')
        q0 *= amp / at_sensors
    sim = start(scene, q0=q0)
    window = cfg['window']
    try:
        samples = sim.advance_to(cfg['duration'])
    except Divergence as exc:   # grew past what floating point carries: unstable
        rates = window_impact_rates(sim.take_events(), sim.impactor_names, sim.t - window,
                                    sim.t)
        return {'stable': False, 'rms_radial_m': None, 'previous_rms_radial_m': None,
                'growth_ratio': None, 'growth_rate_1_s': None, 'diverged_at_s': exc.t,
                'divergence': exc.what, 'impacts_per_second': sum(rates.values()),
                'impactor_rates_per_second': rates,
                'resolved': {k: lookup(scene.scene, k) for k in p.get('keys', ())}}
    t = samples.t
    r2 = np.sum(samples.displacement[:, idx] ** 2, axis=1)
    last = t > t[-1] - window
    prev = (t > t[-1] - 2 * window) & ~last
    with np.errstate(all='ignore'):
        r1 = float(np.sqrt(np.mean(r2[last])))
        r0 = float(np.sqrt(np.mean(r2[prev]))) if prev.any() else float('nan')
        ratio = r1 / r0 if r0 > 0 else float('inf') if r1 > 0 else 1.0
    limit = p.get('max_amplitude')
    unstable = (not math.isfinite(r1) or not ratio <= 1.0 + p.get('growth_tol', 0.05)
                or (limit is not None and r1 > limit))
    rates = window_impact_rates(sim.take_events(), sim.impactor_names, sim.t - window, sim.t)
    return {'stable': not unstable, 'rms_radial_m': finite_or_none(r1),
            'previous_rms_radial_m': finite_or_none(r0), 'growth_ratio': finite_or_none(ratio),
            'growth_rate_1_s': finite_or_none(math.log(ratio) / window)
            if ratio > 0 and math.isfinite(ratio) else None, 'diverged_at_s': None,
            'impacts_per_second': sum(rates.values()), 'impactor_rates_per_second': rates,
            'resolved': {k: lookup(scene.scene, k) for k in p.get('keys', ())}}


def make_points(scene, kcc_key, kccs, overrides=(), *, weight_keys=(), weights=(),
                clearance_keys=(), clearances=(), baseline=True, params=None, seed=0):
    """Points of a stability map.

    Parameters
    ----------
    scene : str
        Scene name or path.
    kcc_key : str
        Scene key of the cross-coupled stiffness, e.g. ``structure.cross_couplings.0.kcc``.
    kccs : sequence of str
        Its values (override text: ``'8500 lb/in'``; a plain number is N/m).
    overrides : sequence of str
        Base overrides.
    weight_keys, clearance_keys : sequence of str
        Concrete keys set to each weight (e.g. ``impactors.0.mass`` and a housing mass) and
        each clearance; every key of a group gets the same value (:func:`stability` expands
        a ``*`` list index into these).
    weights, clearances : sequence of str
        Values (units allowed: ``'3 lb'``, ``'6.9 mil'``); empty = the scene's.
    baseline : bool
        Add one run without impactors per Kcc.
    params : dict
        Task parameters (see :func:`verdict`).
    seed : int
        Study seed.

    Returns
    -------
    list of Point
    """
    params = dict(params or {})
    params['keys'] = [kcc_key] + list(weight_keys[:1]) + list(clearance_keys[:1])
    points = []

    def add(extra, labels):
        ov = list(overrides) + extra
        points.append(Point(verdict, scene, tuple(ov), point_seed(seed, '\n'.join([scene] + ov)),
                            params, labels))

    for kcc in kccs:
        if baseline:
            add([f'{kcc_key}={kcc}', 'impactors=[]'],
                {'kcc': kcc, 'weight': None, 'clearance': None, 'impactors': False})
        for w in (weights or [None]):
            for c in (clearances or [None]):
                extra = [f'{kcc_key}={kcc}']
                extra += [f'{k}={w}' for k in weight_keys] if w is not None else []
                extra += [f'{k}={c}' for k in clearance_keys] if c is not None else []
                add(extra, {'kcc': kcc, 'weight': w, 'clearance': c, 'impactors': True})
    return points


def onset(scene, kcc_key, overrides=(), *, bracket=None, start_hi=None, rtol=1e-6):
    """Linear onset of instability without impactors, by bisection on Kcc.

    Parameters
    ----------
    scene : str
        Scene name or path.
    kcc_key : str
        Scene key of the cross-coupled stiffness.
    overrides : sequence of str
        Base overrides (``impactors=[]`` is added).
    bracket : (float, float), optional
        ``(lo, hi)`` (N/m) with a stable ``lo`` and an unstable ``hi``. Default: ``lo = 0``
        and ``hi`` doubled from ``start_hi`` (default 1 N/m) until unstable.
    start_hi : float, optional
        First ``hi`` of the automatic bracket (N/m).
    rtol : float
        Relative width of the final bracket (dimensionless).

    Returns
    -------
    dict
        ``onset_kcc_N_m``, ``bracket_N_m``, ``whirl_frequency_hz`` (imaginary part of the
        critical eigenvalue over 2 pi) and ``evaluations``.
    """
    from ..modal.stability import least_damped_eigenvalue, onset_cross_coupling
    from ..scene.build import load
    base = list(overrides) + ['impactors=[]']
    count = [0]

    def matrices(kcc):
        count[0] += 1
        s = load(scene, base + [f'{kcc_key}={float(kcc)!r}'])
        return s.model.K, s.model.C   # the simulated matrices: gyroscopic coupling included

    def growth(kcc):
        return least_damped_eigenvalue(*matrices(kcc)).real

    if bracket is not None:
        lo, hi = map(float, bracket)
    else:
        lo, hi = 0.0, float(start_hi or 1.0)
        if growth(lo) >= 0:
            raise ValueError(f'the scene is not stable at {kcc_key}=0 without impactors '
                             f'(max Re(lambda) = {growth(lo):.4g} 1/s); no onset to find')
        for _ in range(80):
            if growth(hi) > 0:
                break
            lo, hi = hi, 2.0 * hi
        else:
            raise ValueError(f'no instability found up to {kcc_key}={hi:.4g} N/m')
    kcc = onset_cross_coupling(matrices, lo, hi, rtol=rtol)
    lam = least_damped_eigenvalue(*matrices(kcc))
    return {'kcc_key': kcc_key, 'onset_kcc_N_m': kcc, 'bracket_N_m': [lo, hi],
            'whirl_frequency_hz': abs(lam.imag) / (2 * math.pi), 'evaluations': count[0]}


def stability(scene, kcc_key, kccs=(), overrides=(), *, weight_keys=(), weights=(),
              clearance_keys=(), clearances=(), baseline=True, sensors=None,
              perturbation=1e-6, growth_tol=0.05, max_amplitude=None, find_onset=False,
              onset_bracket=None, verify=False, seed=0, executor='process', workers=None,
              dask_address=None, progress=None):
    """Stability map (and optionally the linear onset).

    Parameters
    ----------
    scene, kcc_key, kccs, overrides, weight_keys, weights, clearance_keys, clearances, baseline
        See :func:`make_points`; a key may have a ``*`` list index, as in a sweep's grid
        (``impactors.*.mass``: every impactor's, see :func:`.sweep.expand_key`).
    sensors : sequence of str, optional
        Sensors of the radial amplitude; default all.
    perturbation : float
        Initial displacement at the sensors (m).
    growth_tol : float
        Growth tolerance of the criterion (dimensionless).
    max_amplitude : float, optional
        RMS radial amplitude above which a point is unstable (m).
    find_onset : bool
        Also compute :func:`onset`.
    onset_bracket : (float, float), optional
        See :func:`onset`.
    verify : bool
        Tell physical from numerical instability: re-run every point with ``simulation.dt``
        halved and with the other method (see :func:`verification_settings`), from the same
        perturbation, and report whether the verdict changes.
    seed, executor, workers, dask_address, progress
        See :func:`.runner.run_points`.

    Returns
    -------
    dict
        ``study``, ``scene``, ``criterion``, ``rows`` (per point: ``kcc``, ``weight``,
        ``clearance`` as given, ``kcc_N_m``, ``impactors``, ``verdict``,
        ``rms_radial_m``, ``growth_ratio``, ``growth_rate_1_s``, ``diverged_at_s`` (s, or
        None; a run that outgrew floating point has no ratio), ``impacts_per_second``;
        with ``verify``: ``verdict_half_dt``, ``verdict_other_method`` (and their
        ``growth_ratio_*``, ``rms_radial_m_*``, ``diverged_at_s_*``) and ``verified``, True
        when all three verdicts agree), ``onset`` (or None), ``verification`` (the checks'
        settings, or None), ``scene_weight`` and ``scene_clearance`` (the scene's own
        impactors, shown where a row keeps them), ``points``, ``failures``, ``wall_time_s``.
    """
    from ..scene.build import load
    if not weights and weight_keys:
        weight_keys = ()
    if not clearances and clearance_keys:
        clearance_keys = ()
    if (weights and not weight_keys) or (clearances and not clearance_keys):
        raise ValueError('weights and clearances need their scene keys '
                         '(--weight-key, --clearance-key)')
    base = load(scene, list(overrides))
    from .measure import check_memory
    check_memory(base)
    from .sweep import expand_key
    weight_keys = [k for key in weight_keys for k in expand_key(key, base.scene, '--weight-key')]
    clearance_keys = [k for key in clearance_keys
                      for k in expand_key(key, base.scene, '--clearance-key')]
    from .measure import lookup
    if kccs and lookup(base.scene, kcc_key) is None:
        couplings = base.scene['structure'].get('cross_couplings') or []
        raise ValueError(f'--kcc-key {kcc_key}: no such key in scene {base.name} (it has '
                         f'{len(couplings)} structure.cross_couplings entr'
                         f"{'y' if len(couplings) == 1 else 'ies'}; a stability map needs "
                         'a cross-coupled stiffness, e.g. scene rbs_kcc)')
    start = time.perf_counter()
    found = None
    if find_onset:
        hi = max([_si(k) for k in kccs] + [1.0]) if kccs else None
        found = onset(scene, kcc_key, overrides, bracket=onset_bracket, start_hi=hi)
    params = {'sensors': list(sensors) if sensors else None, 'perturbation': perturbation,
              'growth_tol': growth_tol, 'max_amplitude': max_amplitude}
    points = make_points(scene, kcc_key, kccs, overrides, weight_keys=weight_keys,
                         weights=weights, clearance_keys=clearance_keys,
                         clearances=clearances,
                         baseline=baseline and bool(base.scene['impactors']), params=params,
                         seed=seed)
    checks = verification_settings(base) if verify else None
    if checks:
        extra = []
        for p in points:
            for name in ('half_dt', 'other_method'):
                ov = tuple(p.overrides) + tuple(checks[name]['overrides'])
                # same seed: the same initial perturbation as the point checked
                extra.append(Point(p.task, p.scene, ov, p.seed, p.params,
                                   dict(p.labels, check=name)))
        points = points + extra
    results = run_points(points, executor, workers=workers, dask_address=dask_address,
                         progress=progress) if points else []
    wall = time.perf_counter() - start
    n_main = len(results) // 3 if checks else len(results)
    rows = []
    for i, r in enumerate(results[:n_main]):
        lab, v = r.point.labels, r.value
        rows.append({'kcc': lab['kcc'], 'weight': lab['weight'], 'clearance': lab['clearance'],
                     'impactors': lab['impactors'],
                     'kcc_N_m': v['resolved'].get(kcc_key) if r.ok else _si(lab['kcc']),
                     'verdict': ('stable' if v['stable'] else 'unstable') if r.ok else 'error',
                     'rms_radial_m': v['rms_radial_m'] if r.ok else None,
                     'growth_ratio': v['growth_ratio'] if r.ok else None,
                     'growth_rate_1_s': v['growth_rate_1_s'] if r.ok else None,
                     'diverged_at_s': v.get('diverged_at_s') if r.ok else None,
                     'impacts_per_second': v['impacts_per_second'] if r.ok else None,
                     'error': r.error})
        if checks:
            names = []
            for c, name in enumerate(('half_dt', 'other_method')):
                rc = results[n_main + 2 * i + c]
                rows[-1][f'verdict_{name}'] = (
                    ('stable' if rc.value['stable'] else 'unstable') if rc.ok else 'error')
                rows[-1][f'growth_ratio_{name}'] = rc.value['growth_ratio'] if rc.ok else None
                rows[-1][f'diverged_at_s_{name}'] = (rc.value.get('diverged_at_s') if rc.ok
                                                     else None)
                rows[-1][f'rms_radial_m_{name}'] = rc.value['rms_radial_m'] if rc.ok else None
                if not rc.ok:
                    rows[-1][f'error_{name}'] = rc.error
                names.append(rows[-1][f'verdict_{name}'])
            rows[-1]['verified'] = (rows[-1]['verdict'] != 'error'
                                    and all(n == rows[-1]['verdict'] for n in names))
    criterion = (f'unstable when RMS radial amplitude over the last window / previous window '
                 f'> {1 + growth_tol:g}' + (f' or > {max_amplitude:g} m' if max_amplitude
                                            else '') + ', or not finite')
    return {'study': 'stability', 'scene': base.name, 'source': base.source,
            'overrides': list(overrides), 'kcc_key': kcc_key, 'criterion': criterion,
            'window_s': base.scene['simulation']['window'],
            'duration_s': base.scene['simulation']['duration'], 'rows': rows, 'onset': found,
            'verification': checks, **_scene_impactors(base),
            'points': [point_record(r) for r in results],
            'failures': [failure(r) for r in results if not r.ok], 'wall_time_s': wall}


def verification_settings(base):
    """The two re-runs of ``--verify`` for a built scene.

    ``half_dt``: the scene's method at ``simulation.dt / 2``. ``other_method``: ``newmark``
    for a scene run with ``exact``, else ``exact``; Newmark takes the scene's dt halved until
    it is at most a tenth of the highest retained mode's period (its event-tracking limit).

    Parameters
    ----------
    base : SceneModel
        The built scene (with the study's overrides).

    Returns
    -------
    dict
        ``half_dt`` and ``other_method``, each ``method``, ``dt_s`` (s) and ``overrides``.
    """
    from ..integrate.newmark import MIN_STEPS_PER_PERIOD
    cfg = base.scene['simulation']
    method, dt = cfg['method'], cfg['dt']
    other = 'newmark' if method == 'exact' else 'exact'
    dt_other = dt
    if other == 'newmark':
        limit = 1.0 / (MIN_STEPS_PER_PERIOD * float(base.basis.frequencies_hz.max()))
        while dt_other > limit:
            dt_other /= 2
    return {'half_dt': {'method': method, 'dt_s': dt / 2,
                        'overrides': [f'simulation.dt={dt / 2!r}']},
            'other_method': {'method': other, 'dt_s': dt_other,
                             'overrides': [f'simulation.method={other}',
                                           f'simulation.dt={dt_other!r}']}}


def _scene_impactors(base):
    """The scene's own impactor weight and clearance, for rows that keep them (text)."""
    imps = base.scene['impactors']
    if not imps:
        return {'scene_weight': None, 'scene_clearance': None}
    masses = {float(imp.mass) for imp in base.model.impactors}   # mass_ratio resolved
    gaps = {imp['clearance'] for imp in imps}
    if len(masses) == 1:
        weight = f'{len(imps)} x {next(iter(masses)):.4g} kg' if len(imps) > 1 \
            else f'{next(iter(masses)):.4g} kg'
    else:
        weight = 'scene'
    gap = f'{next(iter(gaps)):.4g} m' if len(gaps) == 1 else 'scene'
    return {'scene_weight': weight, 'scene_clearance': gap}


def _si(text):
    """Kcc override text to N/m (None if unreadable)."""
    from ..scene.units import UnitError, parse_quantity
    try:
        return abs(parse_quantity(text, 'stiffness'))
    except (UnitError, ValueError, TypeError):
        return None


def plot(result, path):
    """Plot the steady RMS radial amplitude versus Kcc, unstable points marked.

    Parameters
    ----------
    result : dict
        Output of :func:`stability`.
    path : str or os.PathLike
        PNG file (Agg backend).
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    import numpy as np

    from .display import axis_unit
    unit, factor = axis_unit(result['kcc_key'], [row['kcc'] for row in result['rows']])
    unit, factor = (unit, factor) if unit else ('N/m', 1.0)
    from .plot_style import log_ticks
    groups = {}
    for row in result['rows']:
        if row['kcc_N_m'] is not None and row['verdict'] != 'error':
            groups.setdefault((row['impactors'], row['weight'], row['clearance']), []).append(row)
    # diverged runs and absurd amplitudes (over 1 m) sit in a strip above the axes, not at
    # 1e43 m and not at a made-up value inside the scale
    off_m = 1.0

    def on_scale(r):
        return r['rms_radial_m'] is not None and r['rms_radial_m'] <= off_m

    rows_all = [r for rows in groups.values() for r in rows]
    off = [r for r in rows_all if not on_scale(r)]
    if off:
        fig, (strip, ax) = plt.subplots(2, 1, sharex=True, figsize=(7, 4.9), dpi=120,
                                        gridspec_kw={'height_ratios': [1, 8]})
        strip.set_ylim(0, 1)
        strip.set_yticks([])
        strip.set_ylabel('off\nscale', rotation=0, ha='right', va='center', fontsize=8)
        strip.tick_params(axis='x', labelbottom=False)
        strip.grid(True, axis='x', alpha=0.3)
    else:
        fig, ax = plt.subplots(figsize=(7, 4.5), dpi=120)
    for k, ((imp, w, c), rows) in enumerate(groups.items()):
        color = f'C{k % 10}'
        label = 'no impactors' if not imp else (
            f"W={w if w is not None else result.get('scene_weight')}, "
            f"D={c if c is not None else result.get('scene_clearance')}")
        xs = np.array([r['kcc_N_m'] / factor for r in rows])
        ys = np.array([r['rms_radial_m'] if on_scale(r) else np.nan for r in rows])
        stable = np.array([r['verdict'] == 'stable' for r in rows])
        # the group's legend entry is its line when it has a point on the scale, else
        # its off-scale markers
        segment = bool((np.isfinite(ys[1:]) & np.isfinite(ys[:-1])).any())
        drawn = bool(np.isfinite(ys).any())
        ax.plot(xs, ys, '-', color=color, label=label if segment else None)
        ax.plot(xs[stable], ys[stable], 'o', color=color,
                label=label if drawn and not segment and np.isfinite(ys[stable]).any()
                else None)
        ax.plot(xs[~stable], ys[~stable], 'x', color=color,
                label=label if drawn and not segment and not np.isfinite(ys[stable]).any()
                else None)
        if off and not np.isfinite(ys).all():
            strip.plot(xs[~np.isfinite(ys)], np.full((~np.isfinite(ys)).sum(), 0.5), '^',
                       color=color, ms=8,
                       label=None if drawn else f'{label} (all off scale)')
    if result['onset']:
        ax.axvline(result['onset']['onset_kcc_N_m'] / factor, color='k', ls=':',
                   label='linear onset')
        if off:
            strip.axvline(result['onset']['onset_kcc_N_m'] / factor, color='k', ls=':')
    finite = [r['rms_radial_m'] for r in rows_all if on_scale(r) and r['rms_radial_m'] > 0]
    if finite:
        ax.set_yscale('log')
        log_ticks(ax.yaxis, min(finite) / 1.15, max(finite) * 1.15)
    else:       # every run off scale (or none): an empty linear axis says so
        ax.set_ylim(0, 1)
        ax.set_yticks([])
        ax.text(0.5, 0.5, 'no run on the scale', ha='center', va='center', fontsize=10,
                transform=ax.transAxes)
    xs = [r['kcc_N_m'] / factor for r in rows_all] + (
        [result['onset']['onset_kcc_N_m'] / factor] if result['onset'] else [])
    if xs:      # the onset line too, off the frame
        pad = 0.05 * (max(xs) - min(xs)) or 0.05 * abs(max(xs)) or 1.0
        ax.set_xlim(min(xs) - pad, max(xs) + pad)
    ax.set_xlabel(f'Kcc ({unit})')
    ax.set_ylabel('RMS radial amplitude, last window (m)')
    (strip if off else ax).set_title(
        f"stability: {result['scene']} (o stable, x unstable"
        + (f', ^ diverged or > {off_m:g} m)' if off else ')'))
    ax.grid(True, alpha=0.3)
    handles = [h for a in fig.axes for h in a.get_legend_handles_labels()[0]]
    if handles:
        ax.legend(handles=handles, fontsize=8)
    fig.tight_layout(h_pad=0.3)
    fig.savefig(path, dpi=120)
    plt.close(fig)
