"""What every study plot keeps to, so that it reads at the size it is looked at.

The rule (issue 27, checked by ``test/test_plots.py`` on each plot's Matplotlib figure):

* A plot is looked at at its saved pixel size (a docs page shows a PNG of at most about
  1000 px wide at 1:1): figures are at most :data:`MAX_WIDTH_PX` wide at the DPI they are
  saved with, and every drawn text is at least :data:`MIN_FONT_PT` points at that DPI, i.e.
  at least ``MIN_FONT_PT * dpi / 72`` pixels (13.3 px at 120 dpi, 12.2 px at 110 dpi) tall
  in the PNG.
* Nothing is clipped: every drawn text lies inside the figure, and labels the code places
  next to points lie inside their axes.
* No two drawn texts overlap; labels that would overlap another label, a marker or the
  legend are left out (the tables next to the plots hold every value).
* Every legend entry names an artist that has at least one finite point inside its axes.
* A log axis shows at least four labelled ticks (:func:`log_ticks`).
"""
from __future__ import annotations

import math

#: Smallest font size (points at the saved DPI).
MIN_FONT_PT = 8.0
#: Widest figure (pixels at the saved DPI).
MAX_WIDTH_PX = 1000

#: Candidate label offsets (points) and alignments, tried in order.
_OFFSETS = [(d * dx, d * dy, ha, va) for d in (1, 2.5)
            for dx, dy, ha, va in ((4, 3, 'left', 'bottom'), (4, -3, 'left', 'top'),
                                   (-4, 3, 'right', 'bottom'), (-4, -3, 'right', 'top'),
                                   (0, 6, 'center', 'bottom'), (0, -6, 'center', 'top'),
                                   (7, 0, 'left', 'center'), (-7, 0, 'right', 'center'))]


def log_ticks(axis, lo, hi):
    """Limits and labelled ticks of a log axis holding data in ``[lo, hi]`` (both > 0).

    Over three decades or more: ticks at the powers of ten, limits rounded out to them
    (at least four labels). Under three decades: ticks at 1, 2 and 5 times the powers of
    ten, or at 1 to 9 times when that gives fewer than four (then at least four), limits
    rounded out to a tick, every tick labelled. Minor ticks are never labelled (Matplotlib
    labels them on short axes, where they pile up).

    Parameters
    ----------
    axis : matplotlib.axis.Axis
        ``ax.xaxis`` or ``ax.yaxis`` of an axes whose scale is already ``'log'``.
    lo, hi : float
        Smallest and largest value to show (same unit as the data).
    """
    from matplotlib.ticker import LogFormatterSciNotation, LogLocator, NullFormatter
    lo_d, hi_d = math.floor(math.log10(lo)), math.ceil(math.log10(hi))
    hi_d = max(hi_d, lo_d + 1)
    subs = (1.0,)
    limits = (10.0 ** lo_d, 10.0 ** hi_d)
    if hi_d - lo_d < 4:     # fewer than three whole decades between the data's ends
        for subs in ((1.0, 2.0, 5.0), tuple(float(m) for m in range(1, 10))):
            ticks = [m * 10.0 ** k for k in range(lo_d, hi_d + 2) for m in subs]
            i = max(i for i, t in enumerate(ticks) if t <= lo * (1 + 1e-9))
            j = min(j for j, t in enumerate(ticks) if t >= hi * (1 - 1e-9))
            if j - i >= 3:
                break
        j = max(j, i + 3)       # 1 to 9: widened to four ticks
        limits = (ticks[i], ticks[j])
    (axis.axes.set_xlim if axis.axis_name == 'x' else axis.axes.set_ylim)(*limits)
    axis.set_major_locator(LogLocator(subs=subs))
    # every tick labelled (by default a subset that depends on the span)
    axis.set_major_formatter(LogFormatterSciNotation(labelOnlyBase=False,
                                                     minor_thresholds=(math.inf, math.inf)))
    axis.set_minor_formatter(NullFormatter())


def place_labels(ax, items, *, fontsize=MIN_FONT_PT, avoid=(), marker_pt=3.5):
    """Label points without overlap: each label goes to the first free spot around its point.

    Call after the layout is final (``fig.tight_layout()``): the spots are measured in
    pixels. A label is placed where it lies inside the axes and overlaps no label placed
    before it, no marker and no box of ``avoid``; a label with no such spot is left out.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    items : sequence of (x, y, str, color)
        Points in data coordinates, in order of priority.
    fontsize : float
        Points.
    avoid : sequence of matplotlib.transforms.Bbox
        Display boxes to keep clear (e.g. the legend's).
    marker_pt : float
        Half width of the square kept clear around every point of ``items`` (points).

    Returns
    -------
    int
        Labels left out.
    """
    import numpy as np
    from matplotlib.transforms import Bbox
    fig = ax.figure
    renderer = fig.canvas.get_renderer()
    inside = ax.get_window_extent(renderer)
    half = marker_pt * fig.dpi / 72.0
    xy = ax.transData.transform(np.array([(x, y) for x, y, _, _ in items], dtype=float)
                                .reshape(-1, 2))
    taken = list(avoid) + [Bbox.from_extents(px - half, py - half, px + half, py + half)
                           for px, py in xy if np.isfinite(px) and np.isfinite(py)]
    left_out = 0
    scale = fig.dpi / 72.0
    for (x, y, text, color), (px, py) in zip(items, xy):
        ann = ax.annotate(text, (x, y), xytext=(0, 0), textcoords='offset points',
                          ha='left', va='bottom', fontsize=fontsize, color=color)
        size = ann.get_window_extent(renderer)   # measured once; each spot by arithmetic
        w, h = size.width, size.height
        for dx, dy, ha, va in _OFFSETS:
            x0 = px + dx * scale - {'left': 0.0, 'center': w / 2, 'right': w}[ha]
            y0 = py + dy * scale - {'bottom': 0.0, 'center': h / 2, 'top': h}[va]
            box = Bbox.from_bounds(x0, y0, w, h)
            if (box.x0 >= inside.x0 and box.x1 <= inside.x1 and box.y0 >= inside.y0
                    and box.y1 <= inside.y1 and not any(box.overlaps(t) for t in taken)):
                ann.xyann = (dx, dy)
                ann.set_horizontalalignment(ha)
                ann.set_verticalalignment(va)
                taken.append(box)
                break
        else:
            ann.remove()
            left_out += 1
    return left_out
