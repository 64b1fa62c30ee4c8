"""Every study plot checked at the size a reader sees it (issue 27, item 5).

The rule (``impact_damper_sim/studies/plot_style.py``): a PNG is looked at at its saved pixel
size, so each figure is drawn at the DPI it is saved with and

* is at most 1000 px wide (a docs page shows it at 1:1),
* every text drawn is at least 8 pt at that DPI (a font size of ``8 * dpi / 72`` px in the
  PNG: 13.3 px at 120 dpi, 12.2 px at 110 dpi),
* every text drawn lies inside the figure, labels placed next to points inside their axes,
* no two texts drawn overlap (tick labels, point labels, legend, titles) by more than 1 px,
* every legend entry names an artist with at least one finite point inside its axes (a line
  without markers: two neighbouring ones, since a point alone draws nothing),
* every log axis shows at least four labelled ticks;

and each test adds what its plot's reader complained of (issue 27): '1 mode', off-scale
markers above the data, a stuck lane labelled on its own line, one colour per swept group.

Each plot function runs on small inputs (synthetic results, the shipped convergence and
cost-curve data); the figure it saves is caught at ``savefig`` and drawn again here with
Agg at the saved DPI, recording what the renderer actually draws.
"""
import csv
import importlib.util
import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest

matplotlib = pytest.importorskip('matplotlib')
matplotlib.use('Agg')
from matplotlib.backends.backend_agg import RendererAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.text import Annotation, Text  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
MIN_PT, MAX_WIDTH_PX = 8.0, 1000
TOL_PX = 1.0


# --- catching and drawing a saved figure -------------------------------------------------------

@pytest.fixture
def saved(monkeypatch):
    """``[(figure, dpi)]`` of every figure saved while the test runs."""
    figs = []
    original = Figure.savefig

    def savefig(self, fname, *args, **kwargs):
        figs.append((self, kwargs.get('dpi') or self.dpi))
        return original(self, fname, *args, **kwargs)

    monkeypatch.setattr(Figure, 'savefig', savefig)
    return figs


class Drawn:
    """What the renderer drew: ``texts`` [(Text, size in points, display Bbox)]."""

    def __init__(self, fig, dpi):
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        self.fig, self.dpi, self.texts = fig, dpi, []
        if not isinstance(fig.canvas, FigureCanvasAgg):   # pyplot's close() detaches it
            FigureCanvasAgg(fig)
        fig.set_dpi(dpi)
        current, seen = [], {}
        draw, draw_text = Text.draw, RendererAgg.draw_text

        def text_draw(text, renderer):
            current.append(text)
            try:
                return draw(text, renderer)
            finally:
                current.pop()

        def renderer_draw_text(renderer, gc, x, y, s, prop, angle, ismath=False, mtext=None):
            if current and s.strip():
                seen.setdefault(id(current[-1]), (current[-1], prop.get_size_in_points()))
            return draw_text(renderer, gc, x, y, s, prop, angle, ismath, mtext)

        Text.draw, RendererAgg.draw_text = text_draw, renderer_draw_text
        try:
            fig.canvas.draw()
        finally:
            Text.draw, RendererAgg.draw_text = draw, draw_text
        self.renderer = fig.canvas.get_renderer()
        self.texts = [(t, size, t.get_window_extent(self.renderer))
                      for t, size in seen.values()]

    def strings(self):
        return [t.get_text() for t, _, _ in self.texts]


def inside(box, outer, tol=TOL_PX):
    return (box.x0 >= outer.x0 - tol and box.x1 <= outer.x1 + tol
            and box.y0 >= outer.y0 - tol and box.y1 <= outer.y1 + tol)


def points_drawn(artist):
    """Display coordinates of an artist's data points that are finite and inside its axes."""
    from matplotlib.collections import Collection
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    if not artist.get_visible():
        return np.empty((0, 2))
    if isinstance(artist, Line2D):
        if artist.get_linestyle() in ('None', '') and artist.get_marker() in ('None', '', None):
            return np.empty((0, 2))
        xy = artist.get_transform().transform(np.asarray(artist.get_xydata(), dtype=float))
    elif isinstance(artist, Collection):
        offsets = np.asarray(artist.get_offsets(), dtype=float)
        xy = artist.get_offset_transform().transform(offsets) if offsets.size else offsets
    elif isinstance(artist, Patch):
        xy = artist.get_transform().transform(artist.get_path().vertices)
    else:
        raise AssertionError(f'no rule for a legend entry drawn by {type(artist).__name__}')
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    box = artist.axes.bbox
    keep = (np.isfinite(xy).all(axis=1) & (xy[:, 0] >= box.x0 - TOL_PX)
            & (xy[:, 0] <= box.x1 + TOL_PX) & (xy[:, 1] >= box.y0 - TOL_PX)
            & (xy[:, 1] <= box.y1 + TOL_PX))
    if isinstance(artist, Line2D) and artist.get_marker() in ('None', '', None):
        # a line without markers draws nothing at a point alone: two neighbours needed
        keep = keep & (np.r_[keep[1:], False] | np.r_[False, keep[:-1]])
    return xy[keep]


def legend_entries(fig):
    """``[(label, [artists of the figure carrying that label])]`` of every legend."""
    artists = [a for ax in fig.axes for a in ax.get_children()]
    containers = {c.get_label(): list(c.get_children()) for ax in fig.axes
                  for c in ax.containers}
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend()] + list(fig.legends)
    return [(t.get_text(), [a for a in artists if a.get_label() == t.get_text()]
             + containers.get(t.get_text(), []))
            for legend in legends for t in legend.get_texts()]


def check_readable(fig, dpi, *, extra=()):
    """The rule of this module (every breach listed at once); returns the :class:`Drawn`.

    ``extra``: problems found by the caller, reported with the others.
    """
    problems = list(extra)
    width = fig.get_figwidth() * dpi
    if width > MAX_WIDTH_PX:
        problems.append(f'figure {width:.0f} px wide (at most {MAX_WIDTH_PX})')
    drawn = Drawn(fig, dpi)
    assert drawn.texts, 'nothing drawn'
    small = [(t.get_text(), size) for t, size, _ in drawn.texts if size < MIN_PT - 1e-9]
    if small:
        problems.append(f'{len(small)} texts under {MIN_PT:g} pt at {dpi} dpi: {small[:6]}')
    clipped = [t.get_text() for t, _, box in drawn.texts if not inside(box, fig.bbox)]
    if clipped:
        problems.append(f'texts outside the figure: {clipped}')
    out = [t.get_text() for t, _, box in drawn.texts
           if isinstance(t, Annotation) and not inside(box, t.axes.bbox)]
    if out:
        problems.append(f'{len(out)} labels outside their axes: {out[:6]}')
    overlaps = []
    for (a, _, ba), (b, _, bb) in itertools.combinations(drawn.texts, 2):
        w = min(ba.x1, bb.x1) - max(ba.x0, bb.x0)
        h = min(ba.y1, bb.y1) - max(ba.y0, bb.y0)
        if w > TOL_PX and h > TOL_PX:
            overlaps.append((a.get_text(), b.get_text()))
    if overlaps:
        problems.append(f'{len(overlaps)} pairs of overlapping texts: {overlaps[:6]}')
    for label, artists in legend_entries(fig):
        if not any(len(points_drawn(a)) for a in artists):
            problems.append(f'legend entry {label!r} has nothing drawn inside its axes')
    texts = {id(t) for t, _, _ in drawn.texts}
    for ax in fig.axes:
        for axis, scale in ((ax.xaxis, ax.get_xscale()), (ax.yaxis, ax.get_yscale())):
            if scale != 'log' or not ax.axison:
                continue
            labels = [t for t in axis.get_ticklabels(which='both') if id(t) in texts]
            if len(labels) < 4:
                problems.append(f'log {axis.axis_name} axis of {ax.get_title()!r}: '
                                f'{len(labels)} labelled ticks {[t.get_text() for t in labels]}')
    assert not problems, '\n'.join(problems)
    return drawn


def only(saved):
    assert len(saved) == 1
    return saved[0]


# --- convergence -------------------------------------------------------------------------------

@pytest.mark.parametrize('scene', ['sdof', 'cantilever'])
def test_convergence_pareto(scene, saved, tmp_path):
    """Pareto labels at 8 pt, none overlapping, none past the axes; '1 mode', not '1 modes'."""
    from impact_damper_sim.studies.convergence import plot
    result = json.loads((ROOT / 'docs' / 'convergence' / f'{scene}.json').read_text())
    plot(result, tmp_path / 'p.png')
    fig, dpi = only(saved)
    title, modes = fig._suptitle.get_text(), result['reference']['modes']
    wrong = [] if f" {modes} mode{'s' if modes != 1 else ''})" in title else [f'title {title!r}']
    drawn = check_readable(fig, dpi, extra=wrong)
    labels = [t for t, _, _ in drawn.texts if isinstance(t, Annotation)]
    assert len(labels) >= 5, 'most points unlabelled'


# --- stability ---------------------------------------------------------------------------------

def _stability_result(baseline_rms, cells):
    """A stability result: bare rotor rows (rms or None = diverged) and impacting cells."""
    rows = []
    for kcc, rms in zip((8500, 11250, 13500), baseline_rms):
        rows.append({'kcc': f'{kcc} lb/in', 'weight': None, 'clearance': None,
                     'impactors': False, 'kcc_N_m': kcc * 175.12683524647636,
                     'verdict': 'unstable', 'rms_radial_m': rms, 'growth_ratio': None,
                     'growth_rate_1_s': None, 'diverged_at_s': None if rms else 0.7,
                     'impacts_per_second': 0.0, 'error': None})
    for (kcc, w, rms, stable) in cells:
        rows.append({'kcc': f'{kcc} lb/in', 'weight': w, 'clearance': '6.9 mil',
                     'impactors': True, 'kcc_N_m': kcc * 175.12683524647636,
                     'verdict': 'stable' if stable else 'unstable', 'rms_radial_m': rms,
                     'growth_ratio': 1.0, 'growth_rate_1_s': 0.0, 'diverged_at_s': None,
                     'impacts_per_second': 1500.0, 'error': None})
    return {'study': 'stability', 'scene': 'rbs_kcc', 'kcc_key': 'structure.cross_couplings.0.kcc',
            'rows': rows, 'onset': {'onset_kcc_N_m': 8250 * 175.12683524647636},
            'scene_weight': '6 x 0.2268 kg', 'scene_clearance': '8.763e-05 m'}


CELLS = [(k, w, rms, k < 13500 or w == '3 lb')
         for k, base in ((8500, 2.0e-5), (11250, 3.0e-5), (13500, 2.6e-5))
         for w, rms in (('1.5 lb', base), ('3 lb', 0.6 * base))]


#: Table 4.4.1-like cells: 0.1 to 1.15 mil (the old plot labelled two ticks on this axis)
MIL_CELLS = [(k, w, rms * 25.4e-6, True) for k in (8500, 11250, 13500)
             for w, rms in (('1.5 lb', 0.86), ('3 lb', 0.12), ('6 lb', 1.15))]


@pytest.mark.parametrize('baseline, cells', [
    pytest.param([None, None, None], CELLS, id='bare-rotor-diverged'),
    pytest.param([3e-3, 40.0, None], CELLS, id='bare-rotor-grown-and-off-scale'),
    pytest.param([None, None, None], MIL_CELLS, id='table-4.4.1-cells'),
    pytest.param([None, None, None], [], id='every-run-diverged'),
])
def test_stability(baseline, cells, saved, tmp_path):
    """Every legend entry drawn (the bare rotor's too when all its runs diverged), the
    off-scale runs above the axes' data in their own strip, four or more log labels."""
    from impact_damper_sim.studies.stability import plot
    result = _stability_result(baseline, cells)
    plot(result, tmp_path / 's.png')
    fig, dpi = only(saved)
    Drawn(fig, dpi)
    problems = []
    main = fig.axes[-1]     # the data's axes (below the off-scale strip, if any)
    lo, hi = main.get_ylim()
    on_scale = [r['rms_radial_m'] for r in result['rows']
                if r['rms_radial_m'] is not None and r['rms_radial_m'] <= 1.0]
    if on_scale and main.get_yscale() != 'log':
        problems.append('amplitudes on a linear axis')
    if on_scale and not lo <= min(on_scale) <= max(on_scale) <= hi:
        problems.append(f'on-scale runs {min(on_scale):.3g}..{max(on_scale):.3g} m outside '
                        f'the axis {lo:.3g}..{hi:.3g} m')
    # off-scale runs (diverged, or above 1 m): one marker each, above the axes of the data
    off = [r for r in result['rows'] if r['rms_radial_m'] is None or r['rms_radial_m'] > 1.0]
    markers = [a for ax in fig.axes for a in ax.get_lines() if a.get_marker() == '^']
    xy = np.concatenate([points_drawn(a) for a in markers] or [np.empty((0, 2))])
    xy = np.unique(np.round(xy, 3), axis=0)
    if len(xy) != len(off):
        problems.append(f'{len(xy)} off-scale markers drawn for {len(off)} off-scale runs')
    inside_data = [round((y - main.bbox.y0) / main.bbox.height, 2) for y in xy[:, 1]
                   if y <= main.bbox.y1 + TOL_PX]
    if inside_data:
        problems.append(f'off-scale markers inside the data axes, at {inside_data} of its '
                        'height')
    check_readable(fig, dpi, extra=problems)


# --- report ------------------------------------------------------------------------------------

@pytest.fixture(scope='module')
def one_impactor_log(tmp_path_factory):
    """2 s of a 50 Hz sine, impacts at 10/s, one impactor never stuck."""
    pytest.importorskip('mcap_ros2.writer')
    from test_report import Log, _imu, stamp
    path = tmp_path_factory.mktemp('plots') / 'one.mcap'
    log = Log(path)
    events = [(k * 1_000_000, '/accel/s1', 'sensor_msgs/msg/Imu',
               _imu(k * 1_000_000, math.sin(2 * math.pi * 50 * k / 1000), 0.3, 0.0))
              for k in range(2000)]
    events += [(k * 100_000_000 + 5_000_000, '/impacts', 'geometry_msgs/msg/WrenchStamped',
                {'header': {'stamp': stamp(k * 100_000_000 + 5_000_000),
                            'frame_id': 'housing/imp_a'}, 'wrench': {'force': {'x': 1e-3}}})
               for k in range(20)]
    events += [(t, '/impactor_state', 'sensor_msgs/msg/JointState',
                {'header': {'stamp': stamp(t)}, 'name': ['imp_a/y'], 'position': [0.0],
                 'velocity': [0.0], 'effort': [0.0]}) for t in (0, 1_000_000_000, 1_999_000_000)]
    for t_ns, topic, rtype, msg in sorted(events, key=lambda e: e[0]):
        log.write(topic, rtype, msg, t_ns)
    log.close()
    return path


def test_report(one_impactor_log, saved, tmp_path):
    """The stuck lane's label sits on its trace (never stuck: at its baseline), its
    wording matches its marks (percent of time stuck), texts 8 pt and more."""
    from impact_damper_sim.studies.report import analyze
    from impact_damper_sim.studies.report_output import plot
    report, series = analyze(one_impactor_log)
    plot(report, series, tmp_path / 'r.png')
    fig, dpi = only(saved)
    problems = []
    (ax,) = [a for a in fig.axes if a.get_title().startswith('stuck state')]
    title = ax.get_title()
    labels = [t.get_text() for t in ax.get_yticklabels()]
    if labels != ['imp_a (0 % stuck)']:
        problems.append(f'lane labels {labels}')
    if 'brackets' in title and not all('[' in s for s in labels):
        problems.append(f'title {title!r} against labels {labels}')
    # each lane's label on a line of that lane (its trace or its baseline), not beside it
    traces = [line for line in ax.get_lines() if len(line.get_xdata()) > 2]
    for k, (tick, label) in enumerate(zip(ax.get_yticks(), labels)):
        name = label.split(' (')[0]
        lane = [line for line in ax.get_lines() if line.get_gid() == f'lane:{name}']
        if not any(y.min() - 1e-9 <= tick <= y.max() + 1e-9
                   for y in (np.asarray(line.get_ydata(), dtype=float) for line in lane)):
            y = np.asarray(traces[k].get_ydata(), dtype=float)
            problems.append(f'lane label {label!r} at y = {tick:g}, on no line of its lane '
                            f'(its trace between {y.min():g} and {y.max():g})')
    check_readable(fig, dpi, extra=problems)


# --- frf and sweep -----------------------------------------------------------------------------

def test_frf(saved, tmp_path):
    from impact_damper_sim.studies.frf import plot
    ratios = np.linspace(0.8, 1.2, 9)
    rows = [{'frequency_ratio': float(r), 'settled': i != 4,
             'primary_without_m': 1e-3 / abs(1 - r * r + 0.02j),
             'primary_with_m': 0.6e-3 / abs(1 - r * r + 0.05j)} for i, r in enumerate(ratios)]
    plot({'unit': 'ratio', 'scene': 'sdof', 'sensors': ['primary'], 'rows': rows},
         tmp_path / 'f.png')
    check_readable(*only(saved))


def test_sweep_one_colour_per_group(saved, tmp_path):
    """The run and steady lines of one mass ratio share a colour; mass ratios differ."""
    from impact_damper_sim.studies.sweep import plot
    rows = []
    for mu in ('0.02', '0.04', '0.08'):
        for c, gap in enumerate(('1 mm', '2 mm', '4 mm')):
            row = {'impactors.0.mass_ratio': mu, 'impactors.0.clearance': gap,
                   'impactors.0.mass_ratio_si': float(mu),
                   'impactors.0.clearance_si': float(gap.split()[0]) * 1e-3}
            for k, phase in enumerate(('run', 'steady')):
                row[f'{phase}_worst_acceleration_g'] = 10 + 100 * float(mu) * (c + 1) - k
            rows.append(row)
    result = {'scene': 'sdof', 'objective': 'acceleration', 'best_over': 'impactors.0.clearance',
              'grid': [{'key': 'impactors.0.mass_ratio', 'values': ['0.02', '0.04', '0.08']},
                       {'key': 'impactors.0.clearance', 'values': ['1 mm', '2 mm', '4 mm']}],
              'phases': [{'name': 'run'}, {'name': 'steady'}], 'rows': rows}
    plot(result, tmp_path / 'w.png')
    fig, dpi = only(saved)
    from matplotlib.colors import to_hex
    colours = {}
    for line in fig.axes[0].get_lines():
        mu = line.get_label().split('=')[1].split()[0]
        colours.setdefault(mu, set()).add(to_hex(line.get_color()))
    assert sorted(colours) == ['0.02', '0.04', '0.08']
    problems = ([] if all(len(c) == 1 for c in colours.values())
                and len(set.union(*colours.values())) == 3
                else [f'colours per mass ratio: {colours}'])
    check_readable(fig, dpi, extra=problems)


# --- validation --------------------------------------------------------------------------------

def test_validation_frf(saved, tmp_path):
    from impact_damper_sim.studies.validation_doc import plot_frf
    from impact_damper_sim.studies.validation_setup import F0_OVER_K
    ratios = np.linspace(0.8, 1.2, 21)

    def rows(sensor):
        return [{'frequency_ratio': float(r),
                 f'{sensor}_without_m': F0_OVER_K / abs(1 - r * r + 0.04j),
                 f'{sensor}_with_m': F0_OVER_K / abs(1 - r * r + 0.1j)} for r in ratios]
    plot_frf({'sdof': {'rows': rows('primary')}, 'cantilever': {'rows': rows('tip')}},
             tmp_path / 'frf.png')
    check_readable(*only(saved))


def test_validation_hpotp(saved, tmp_path):
    from impact_damper_sim.scene.units import G0
    from impact_damper_sim.studies.validation_doc import plot_hpotp
    rows = [{'rotor.multiplier': str(x),
             'criticals_without_acceleration_m_s2': 5.6 * x * G0,
             'criticals_worst_acceleration_m_s2': 5.2 * x * G0,
             'full_speed_without_acceleration_m_s2': 0.8 * x * G0,
             'full_speed_worst_acceleration_m_s2': 1.1 * x * G0} for x in (1, 3, 7, 10)]
    plot_hpotp(rows, tmp_path / 'hpotp.png')
    check_readable(*only(saved))


def test_validation_rbs_stability(saved, tmp_path):
    """Table 4.4.1's 18 cells: verdicts and tick labels at 8 pt, none overlapping."""
    from impact_damper_sim.studies.validation_doc import plot_rbs
    from impact_damper_sim.studies.validation_setup import PAPER_4_4_1
    rows = [{'kcc': k, 'weight': None, 'gap': None, 'stable': False, 'rms_mil': None}
            for k in (8500, 11250, 13500)]
    rows += [{'kcc': k, 'weight': w, 'gap': g, 'stable': (i % 3) != 1,
              'rms_mil': 0.1 + 0.05 * i} for i, (k, w, g) in enumerate(PAPER_4_4_1)]
    plot_rbs(rows, tmp_path / 'rbs.png')
    fig, dpi = only(saved)
    drawn = check_readable(fig, dpi)
    verdicts = [s for s in drawn.strings() if s in ('S/S', 'S/U', 'U/S', 'U/U')]
    assert len(verdicts) == 18


# --- bench/impact_cost.py ----------------------------------------------------------------------

def test_impact_cost_curve(saved, tmp_path):
    spec = importlib.util.spec_from_file_location('impact_cost', ROOT / 'bench' / 'impact_cost.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    with open(ROOT / 'docs' / 'impact-cost' / 'cost_curve.csv') as fh:
        rows = [{k: (int(v) if k in ('impactors', 'modes') else float(v)) for k, v in r.items()}
                for r in csv.DictReader(fh)]
    module.plot_curve(rows, tmp_path, 6.0)
    check_readable(*only(saved))
