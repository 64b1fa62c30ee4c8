"""Plots of the rotordynamics studies: the Campbell diagram and the whirl mode shapes.

Kept apart from :mod:`.campbell`, which computes: Matplotlib is imported here only, when a
``--plot`` is asked for. Both plots keep the rules of :mod:`.plot_style` (texts of 8 pt and
more at the saved DPI, nothing clipped, no overlapping labels, a legend entry only for what is
drawn).
"""
from __future__ import annotations

#: Line style of each whirl direction (the Campbell diagram and its legend).
STYLES = {'forward': ('-', 'forward whirl'), 'backward': ('--', 'backward whirl'),
          'none': (':', 'no whirl (planar orbit)')}
DPI = 120


def _figure(width, height):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt, plt.figure(figsize=(width, height), dpi=DPI)


def plot(result, path):
    """Draw the Campbell diagram of :func:`~impact_damper_sim.studies.campbell.campbell_study`.

    Damped natural frequency over speed, one line per tracked branch, its style the whirl
    direction (solid forward, dashed backward, dotted none), a marker per speed coloured by
    the log decrement; the harmonic excitation lines; the critical speeds circled and
    labelled (branch, direction, speed); the onset of instability as a vertical line, or in
    the title when the model is unstable from the first speed. The frequency axis reaches the
    highest harmonic line at the top speed and every unstable branch.

    Parameters
    ----------
    result : dict
        Output of ``campbell_study``.
    path : str or os.PathLike
        Image file (its suffix chooses the format; Agg backend).
    """
    import numpy as np
    from matplotlib.colors import Normalize, TwoSlopeNorm

    from .plot_style import place_labels
    plt, fig = _figure(8.0, 5.8)
    ax = fig.add_subplot(1, 1, 1)
    speeds = np.asarray(result['speeds_rpm'], dtype=float)
    freq = np.array([[np.nan if v is None else v for v in b['frequency_hz']]
                     for b in result['branches']], dtype=float).reshape(-1, speeds.size)
    log_dec = np.array([[np.nan if v is None else v for v in b['log_dec']]
                        for b in result['branches']], dtype=float).reshape(-1, speeds.size)
    # up to the excitation: the highest harmonic line at the top speed (or the lowest branch)
    reach = max(result['harmonics']) * speeds[-1] / 60.0
    lowest = float(np.nanmax(freq[0])) if np.isfinite(freq[0]).any() else 1.0
    highest = float(np.nanmax(freq)) if np.isfinite(freq).any() else 1.0
    top = min(highest * 1.12, max(reach, lowest) * 1.3)
    unstable = np.isfinite(freq) & (np.nan_to_num(log_dec, nan=0.0) < 0)
    if unstable.any():   # an unstable branch is never left above the frame
        top = max(top, float(freq[unstable].max()) * 1.08)
    above = sum(1 for b in range(freq.shape[0]) if np.nanmin(freq[b]) > top)
    labelled = set()
    for b, branch in enumerate(result['branches']):
        dirs = branch['direction']
        for k in range(speeds.size - 1):
            if not (np.isfinite(freq[b, k]) and np.isfinite(freq[b, k + 1])):
                continue
            # a segment takes the direction of its faster end (the spin sets it)
            d = dirs[k + 1] or dirs[k] or 'none'
            style, name = STYLES[d]
            ax.plot(speeds[k:k + 2], freq[b, k:k + 2], style, color='0.25', lw=1.4,
                    label=None if d in labelled else name, zorder=2)
            labelled.add(d)
    finite = log_dec[np.isfinite(log_dec)]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 0.0)
    same = hi - lo <= 1e-3 * max(abs(lo), abs(hi), 1e-3)   # one colour: say the value
    if lo < 0 < hi and not same:
        norm, cmap = TwoSlopeNorm(0.0, lo, hi), 'RdYlGn'
    elif same:
        pad = 0.05 * abs(hi) + 1e-3
        norm, cmap = Normalize(lo - pad, hi + pad), 'viridis'
    else:
        norm, cmap = Normalize(lo, hi), 'viridis'
    xs = np.broadcast_to(speeds, freq.shape)
    ok = np.isfinite(freq) & np.isfinite(log_dec)
    order = np.argsort(-log_dec[ok], kind='stable')   # the least damped drawn on top
    dots = ax.scatter(xs[ok][order], freq[ok][order], c=log_dec[ok][order], cmap=cmap,
                      norm=norm, s=5, zorder=3, linewidths=0)
    bar = fig.colorbar(dots, ax=ax, pad=0.02)
    bar.set_label('log decrement' + (f' (all {0.5 * (lo + hi):.3g})' if same else ''))
    bar.ax.tick_params(labelsize=8)
    for i, h in enumerate(result['harmonics']):
        line = h * speeds / 60.0
        ax.plot(speeds, line, '-', color=f'C{i % 10}', lw=1.0, alpha=0.8,
                label=f'{h:g}X excitation', zorder=1)
    crit = result['critical_speeds']
    if crit:
        ax.plot([c['speed_rpm'] for c in crit], [c['frequency_hz'] for c in crit], 'o',
                mfc='none', mec='k', ms=8, label='critical speed (branch, whirl, rpm)',
                zorder=4)
    onset = result['onset']
    if onset and not onset['from_start']:
        ax.axvline(onset['speed_rpm'], color='C3', ls='-.', lw=1.2,
                   label=f"onset of instability, {onset['speed_rpm']:.5g} rpm")
    ax.set_xlim(speeds[0], speeds[-1])
    ax.set_ylim(0.0, top)
    ax.set_xlabel('rotor speed (rpm)')
    ax.set_ylabel('damped natural frequency (Hz)')
    title = (f"Campbell diagram: {result['scene']} ({result['model']['n_modes']} modes"
             + (f'; {above} branches above the frame' if above else '') + ')')
    if onset and onset['from_start']:
        title += (f"\nunstable from the first speed: branch {onset['branch']}"
                  + (f" ({onset['direction']}, {onset['frequency_hz']:.4g} Hz)"
                     if onset['branch'] is not None else ' (divergence)'))
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    # below the axes, in rows: never over a branch or a crossing
    handles, names = ax.get_legend_handles_labels()
    legend = fig.legend(handles, names, loc='lower center', ncol=3, fontsize=8,
                        frameon=False)
    rows = -(-len(names) // 3)
    fig.tight_layout(rect=(0, (0.12 + 0.2 * rows) / fig.get_figheight(), 1, 1))
    fig.canvas.draw()
    letters = {'forward': 'F', 'backward': 'B', 'none': 'N'}
    items = [(c['speed_rpm'], c['frequency_hz'],
              f"{c['branch']}{letters.get(c['direction'], '')} {c['speed_rpm']:.0f}", 'k')
             for c in crit if c['frequency_hz'] <= top]
    place_labels(ax, items, avoid=[legend.get_window_extent(fig.canvas.get_renderer())])
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def plot_shapes(shapes, path):
    """Draw whirl mode shapes along the shaft (:func:`~.campbell.whirl_shapes`).

    One panel per mode: the orbit's major semi-axis over axial position (solid, largest 1)
    and its signed minor semi-axis (dashed: above zero where the orbit turns with the spin,
    below where against it; zero for a planar orbit).

    Parameters
    ----------
    shapes : dict
        Output of ``whirl_shapes``.
    path : str or os.PathLike
        Image file.
    """
    import math

    import numpy as np
    modes = shapes['modes']
    cols = 1 if len(modes) == 1 else 2
    rows = math.ceil(len(modes) / cols)
    plt, fig = _figure(8.0 if cols == 2 else 6.0, 1.0 + 2.3 * rows)
    x = np.asarray(shapes['axial_m'], dtype=float)
    speed = shapes['rotor_speed_rpm']
    for i, mode in enumerate(modes):
        ax = fig.add_subplot(rows, cols, i + 1)
        ax.axhline(0.0, color='0.6', lw=0.8)
        ax.plot(x, mode['major'], '-o', color='C0', ms=3, label='major semi-axis')
        ax.plot(x, mode['signed_minor'], '--', color='C1',
                label='minor semi-axis (+ with the spin)')
        ax.set_ylim(-1.1, 1.35)
        ax.set_title(f"{mode['mode']}: {mode['frequency_hz']:.5g} Hz, {mode['direction']}, "
                     f"log dec {mode['log_dec']:.3g}", fontsize=9)
        ax.tick_params(labelsize=8)
        ax.grid(True, alpha=0.3)
        if i >= len(modes) - cols:
            ax.set_xlabel('axial position x (m)', fontsize=9)
        if i % cols == 0:
            ax.set_ylabel('orbit (scaled)', fontsize=9)
        if i == 0:
            handles, labels = ax.get_legend_handles_labels()
    at = 'at its speed' if speed is None else f'at {speed:.5g} rpm'
    fig.suptitle(f"whirl mode shapes of {shapes['scene']} {at}", fontsize=10)
    fig.legend(handles, labels, loc='lower center', ncol=2, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.35 / fig.get_figheight(), 1, 1))
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


__all__ = ['plot', 'plot_shapes']
