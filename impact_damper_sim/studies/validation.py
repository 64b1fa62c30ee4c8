"""Validation document: the paper's results next to ours (``study validate``).

One command regenerates ``docs/validation.md`` and its plots (``docs/validation/*.png``):

* Figs. 4.1.2 / 4.1.3: SDOF and cantilever frequency responses with and without impactors
  (:mod:`.frf`; the SDOF scene is given the cantilever's mu, e, D and F0).
* Tables 4.3.1 / 4.3.2: HPOTP worst-case vibration at the criticals (t < 5 s) and at full
  speed (t > 5 s) for X = 1, 3, 7, 10 with W = 25 lb, D = 1.7 mil (:mod:`.sweep`).
* Table 4.4.1: RBS stability map over Kcc, W and D (:mod:`.stability`).
* Table 4.4.2: HPOTP casing stability; only the linear onset Kcc without impactors is
  computed (:func:`.stability.onset`), against the paper's 222,000 lb/in.

Every run of every study is one point of a single :func:`.runner.run_points` call, so the
full document runs in parallel on one pool (longest points first). ``quick`` keeps a subset
that runs in well under a minute (used by the test suite); what it leaves out is said in
the document.

The paper's numbers and our settings are in :mod:`.validation_setup`, the document's tables,
text and plots in :mod:`.validation_doc`: this module makes the points, runs them and writes
the document and its plots.
"""
from __future__ import annotations

import os
import time

from .runner import Point, run_points
from .validation_doc import plot_frf, plot_hpotp, plot_rbs, rbs_table, render
from .validation_setup import (
    HPOTP_BASE,
    HPOTP_KCC,
    HPOTP_PHASES,
    KCC_KEY,
    RBS_CRITERION,
    SDOF_AS_CANTILEVER,
    rbs_cell_overrides,
    settings,
)


def onset_task(point):
    """Task: linear onset Kcc without impactors (``params``: ``kcc_key``, ``start_hi``)."""
    from .stability import onset
    return onset(point.scene, point.params['kcc_key'], list(point.overrides),
                 start_hi=point.params.get('start_hi'))


def make_points(quick=False, seed=0):
    """Every point of the document, tagged by study, longest first.

    Returns
    -------
    (list of Point, dict)
        The points (``labels['study']`` says which part they belong to) and the settings.
    """
    from . import frf as frf_mod
    from . import stability as stab_mod
    from . import sweep as sweep_mod
    s = settings(quick)
    tagged = []

    def tag(points, study):
        for p in points:
            tagged.append(Point(p.task, p.scene, p.overrides, p.seed, p.params,
                                {**p.labels, 'study': study}))

    if s['multipliers']:
        grid = [('rotor.multiplier', [str(x) for x in s['multipliers']])]
        tag(sweep_mod.make_points('hpotp', grid, HPOTP_BASE, phases=HPOTP_PHASES, seed=seed),
            'hpotp')
    if s['onset']:
        tagged.append(Point(onset_task, 'hpotp', tuple(HPOTP_KCC), 0,
                            {'kcc_key': KCC_KEY, 'start_hi': 1e5},
                            {'study': 'hpotp_onset'}))
        # the paper's speed: the scene's default is its first critical (config/scenes/rbs.yaml)
        tagged.append(Point(onset_task, 'rbs', ('rotor.speed.speed=7878 rpm',
                                                'structure.cross_couplings=[{node: 4, kcc: '
                                                '0 lb/in}]'), 0,
                            {'kcc_key': KCC_KEY, 'start_hi': 1e5}, {'study': 'rbs_onset'}))
    kccs = [f'{k} lb/in' for k in s['kccs']]
    tag(stab_mod.make_points('rbs_kcc', KCC_KEY, kccs, s['rbs_overrides'] + ['impactors=[]'],
                             baseline=False, params=RBS_CRITERION, seed=seed), 'rbs_bare')
    for w in s['weights']:
        for d in s['gaps']:
            pts = stab_mod.make_points('rbs_kcc', KCC_KEY, kccs,
                                       s['rbs_overrides'] + rbs_cell_overrides(w, d),
                                       baseline=False, params=RBS_CRITERION, seed=seed)
            for p in pts:
                tagged.append(Point(p.task, p.scene, p.overrides, p.seed, p.params,
                                    {**p.labels, 'weight': w, 'clearance': d,
                                     'study': 'rbs'}))
    common = dict(unit='ratio', n_forcing=1, tol=0.005, max_duration=s['frf_max_duration'],
                  seed=seed)
    tag(frf_mod.make_points('sdof', s['ratios'], overrides=SDOF_AS_CANTILEVER
                            + s['frf_overrides'], **common), 'sdof')
    tag(frf_mod.make_points('cantilever', s['ratios'], overrides=s['frf_overrides'],
                            **common), 'cantilever')
    return tagged, s


def validate(out='docs/validation.md', *, quick=False, workers=None, executor=None, seed=0,
             progress=None):
    """Run every study, write the markdown document and its plots.

    Parameters
    ----------
    out : str or os.PathLike
        Markdown file; plots go to ``<out without .md>/*.png`` (e.g. ``docs/validation/``).
    quick : bool
        Run the quick subset (see :func:`settings`).
    workers : int, optional
        Worker processes (default: the CPU count). ``1`` runs serially in this process.
    executor : str, optional
        ``'process'``, ``'serial'`` or ``'dask'``; default ``'serial'`` for one worker,
        else ``'process'``.
    seed : int
        Study seed.
    progress : bool, optional
        Progress bar on stderr.

    Returns
    -------
    dict
        ``path``, ``plots``, ``wall_time_s``, ``n_points`` and ``failures`` (labels and
        errors of failed points).
    """
    from ..scene.build import load
    from . import frf as frf_mod
    from . import sweep as sweep_mod
    if executor is None:
        executor = 'serial' if workers == 1 else 'process'
    points, s = make_points(quick, seed)
    start = time.perf_counter()
    results = run_points(points, executor, workers=workers, progress=progress)
    wall = time.perf_counter() - start
    by = {}
    for r in results:
        by.setdefault(r.point.labels['study'], []).append(r)
    frfs = {}
    for name, overrides in (('sdof', SDOF_AS_CANTILEVER + s['frf_overrides']),
                            ('cantilever', s['frf_overrides'])):
        frfs[name] = frf_mod.assemble(load(name, overrides), overrides, 'ratio', s['ratios'],
                                      by.get(name, []), wall)
    hpotp = (sweep_mod.tabulate(by['hpotp'], ['rotor.multiplier'],
                                [p[0] for p in HPOTP_PHASES]) if 'hpotp' in by else None)
    onsets = {k: by[k][0] for k in ('hpotp_onset', 'rbs_onset') if k in by}
    out = os.fspath(out)
    plot_dir = os.path.splitext(out)[0]
    os.makedirs(plot_dir, exist_ok=True)
    if os.path.dirname(out):
        os.makedirs(os.path.dirname(out), exist_ok=True)
    plots = {'frf': os.path.join(plot_dir, 'frf.png'),
             'rbs': os.path.join(plot_dir, 'rbs_stability.png')}
    plot_frf(frfs, plots['frf'])
    rbs_rows = rbs_table(by.get('rbs', []), by.get('rbs_bare', []))
    plot_rbs(rbs_rows, plots['rbs'])
    if hpotp:
        plots['hpotp'] = os.path.join(plot_dir, 'hpotp_sweep.png')
        plot_hpotp(hpotp, plots['hpotp'])
    failures = [{'labels': r.point.labels, 'error': r.error} for r in results if not r.ok]
    text = render(quick=quick, s=s, frfs=frfs, hpotp=hpotp, rbs_rows=rbs_rows, onsets=onsets,
                  plots={k: os.path.relpath(v, os.path.dirname(out) or '.')
                         for k, v in plots.items()},
                  failures=failures, wall=wall, n_points=len(points),
                  workers=workers, executor=executor, by=by)
    with open(out, 'w') as fh:
        fh.write(text)
    return {'path': out, 'plots': plots, 'wall_time_s': wall, 'n_points': len(points),
            'failures': failures}
