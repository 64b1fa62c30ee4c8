"""What ``study report`` writes from a report: the text it prints by default
(:func:`print_report`), the rows of ``--csv`` (:func:`csv_rows`, :func:`write_csv`) and the
figure of ``--plot`` (:func:`plot`: a spectrum or waterfall per sensor, the impact rate, a
stuck lane per impactor). It reads only the report dict and the plot arrays that
:func:`.report.analyze` returns, so the tables and the figure change here without touching how a
log is read or what is computed from it.
"""
from __future__ import annotations

import math

import numpy as np

from ..scene.units import G0  # standard gravity (m/s^2), exact
from .report_signals import BIN_S, LANE_DAMPERS_OFF, LANE_STUCK, nonfinite_text

#: The stuck-state lanes' fill while the dampers are off (a grey, apart from every lane colour).
DAMPERS_OFF_COLOR = '0.75'


def csv_rows(report):
    """Flatten a report into ``(section, name, quantity, value, unit)`` rows.

    Parameters
    ----------
    report : dict
        Output of :func:`analyze`.

    Returns
    -------
    list of tuple
    """
    rows = [('log', report['file'], 'duration', report['duration_s'], 's'),
            ('log', report['file'], 'messages', report['message_count'], '')]
    for t in report['topics']:
        rows += [('topic', t['topic'], 'type', t['type'], ''),
                 ('topic', t['topic'], 'count', t['count'], ''),
                 ('topic', t['topic'], 'rate', t['rate_hz'], '1/s'),
                 ('topic', t['topic'], 'frequency', t['frequency_hz'], 'Hz')]
    for s in report['sensors']:
        for stat in ('peak_g', 'rms_g'):
            for axis, v in s[stat].items():
                rows.append(('sensor', s['topic'], f"{stat[:-2]}_{axis}", v, 'g'))
        rows.append(('sensor', s['topic'], 'sample_rate', s['sample_rate_hz'], 'Hz'))
        if s['spectrum']:
            for axis, f in s['spectrum']['dominant_hz'].items():
                rows.append(('sensor', s['topic'], f'dominant_{axis}', f, 'Hz'))
    for imp in report['impacts']:
        rows += [('impacts', imp['topic'], 'count', imp['count'], ''),
                 ('impacts', imp['topic'], 'mean_rate', imp['mean_rate_hz'], '1/s')]
        rows += [('impact_rate', imp['topic'], f"bin_{b['start_s']:g}", b['rate_hz'], '1/s')
                 for b in imp['bins']]
    for st in report['impactor_state']:
        rows += [('stuck_fraction', f"{st['topic']}:{name}", 'stuck_fraction',
                  v['stuck_fraction'], '') for name, v in st['impactors'].items()]
    return rows


def write_csv(report, path):
    """Write :func:`csv_rows` to ``path`` with a header line."""
    import csv
    with open(path, 'w', newline='') as fh:
        writer = csv.writer(fh)
        writer.writerow(['section', 'name', 'quantity', 'value', 'unit'])
        writer.writerows(['' if v is None else v for v in row] for row in csv_rows(report))


def plot(report, series, path):
    """Spectra or waterfalls per sensor, the impact rate and the stuck state (PNG, Agg).

    Parameters
    ----------
    report, series : dict
        Output of :func:`analyze`.
    path : str or os.PathLike
        PNG file.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    sensors = [s for s in report['sensors'] if s['topic'] in series['sensors']
               and series['sensors'][s['topic']]]
    panels = len(sensors) + bool(report['impacts']) + bool(report['impactor_state'])
    fig, axes = plt.subplots(max(panels, 1), 1, figsize=(8, 2.8 * max(panels, 1) + 0.4),
                             squeeze=False)
    axes = list(axes[:, 0])
    for s in sensors:
        ax, arrays = axes.pop(0), series['sensors'][s['topic']]
        if s['waterfall'] and s['waterfall'].get('axis') == 'time':
            _time_waterfall(fig, ax, s, arrays, report.get('commands', ()))
            continue
        if s['waterfall']:
            freq, amp = arrays['waterfall_freq_hz'], arrays['waterfall_amp_g']
            rpm = arrays['waterfall_speed_rad_s'] * 30 / math.pi
            order = np.argsort(rpm, kind='stable')
            db = 20 * np.log10(amp[order] + 1e-12)
            top = float(np.nanmax(db)) if db.size else 0.0
            # 80 dB of range: below it, near-silent slices (standstill) would take the scale
            mesh = ax.pcolormesh(freq, rpm[order], db, shading='nearest', cmap='viridis',
                                 vmin=top - 80.0, vmax=top)
            ax.plot(rpm[order] / 60, rpm[order], 'w--', lw=0.8, label='1x')
            fig.colorbar(mesh, ax=ax, label='amplitude (dB re 1 g)')
            ax.set_xlim(freq[0], freq[-1])
            ax.set_ylabel('rotor speed (rpm)')
            ax.set_title(f"waterfall {s['topic']}")
            ax.legend(fontsize=8, loc='upper left')
        else:
            psd = arrays['psd_g2_hz'][:, 1:]
            top = float(psd.max()) if psd.size else 0.0
            floor = top * 1e-10   # 100 dB below the largest: where plotting stops
            quiet = []
            for i, axis in enumerate('xyz'):
                if not psd[i].max() > floor:   # an axis that does not move: named, not drawn
                    quiet.append(axis)
                    continue
                ax.semilogy(arrays['freq_hz'][1:], np.maximum(psd[i], floor), label=axis)
            if top > 0:
                ax.set_ylim(floor, top * 3)
            if quiet:
                ax.text(0.99, 0.02, f"{', '.join(quiet)}: no signal (not drawn)",
                        ha='right', va='bottom', fontsize=8, transform=ax.transAxes)
            ax.axvline(s['spectrum']['dominant_hz']['total'], color='k', ls=':',
                       label=f"{s['spectrum']['dominant_hz']['total']:.4g} Hz")
            ax.set_ylabel('PSD (g$^2$/Hz)')
            peak, rms = s['peak_g']['magnitude'], s['rms_g']['magnitude']
            ax.set_title(f"spectrum {s['topic']} (peak "
                         + ('n/a' if peak is None else f'{peak:.3g} g') + ', RMS '
                         + ('n/a' if rms is None else f'{rms:.3g} g') + ')')
            ax.legend(fontsize=8)
        ax.set_xlabel('frequency (Hz)')
        ax.grid(True, alpha=0.3)
    if report['impacts']:
        ax = axes.pop(0)
        for imp in report['impacts']:
            a = series['impacts'][imp['topic']]
            starts, widths = np.asarray(a['start_s']), np.asarray(a['width_s'])
            rate = np.nan_to_num(np.asarray(a['rate_hz'], dtype=float))
            full = widths >= BIN_S - 1e-9
            if full.any():
                edges = np.append(starts[full], starts[full][-1] + BIN_S)
                line = ax.stairs(rate[full], edges, label=imp['topic'], lw=1.5,
                                 baseline=None)
                color = line.get_edgecolor()
            else:
                color = None
            # a short last bin is a noisy rate estimate: drawn faint, its width as it is
            for s0, w, r in zip(starts[~full], widths[~full], rate[~full]):
                if w > 0:
                    ax.stairs([r], [s0, s0 + w], color=color, alpha=0.5, ls=':',
                              baseline=None,
                              label=f'{imp["topic"]} last {w:.2g} s (partial bin)')
        mark_commands(ax, report.get('commands', ()))
        ax.set_xlabel('time (s)')
        ax.set_ylabel('impacts/s')
        ax.set_ylim(bottom=0)
        ax.set_title(f'impact rate ({BIN_S:g} s bins)')
        ax.legend(fontsize=8)
        ax.grid(True, alpha=0.3)
    if report['impactor_state']:
        ax, level = axes.pop(0), 0
        origin = series['origin_ns']
        ticks, names = [], []
        lanes = [(st, name, ts) for st in report['impactor_state']
                 for name, ts in series['states'][st['topic']].items()]
        colors = plt.get_cmap('tab20' if len(lanes) > 10 else 'tab10')
        any_dampers_off = False
        for k, (st, name, (t, state)) in enumerate(lanes):
            frac = st['impactors'][name]['stuck_fraction']
            color = colors(k % colors.N)
            x = (t - origin) * 1e-9
            off = state == LANE_DAMPERS_OFF
            # the trace breaks where the dampers are off (NaN), a grey bar fills the gap
            y = np.where(off, np.nan, (state == LANE_STUCK) * 0.6 + level)
            ax.step(x, y, where='post', color=color, gid=f'lane:{name}')
            spans = [(x[i], x[i + 1] - x[i]) for i in np.flatnonzero(off[:-1])]
            if spans:
                # said in the title: a legend would cover the top lane's stuck level
                ax.broken_barh(spans, (level - 0.15, 0.9), color=DAMPERS_OFF_COLOR,
                               gid=f'dampers-off:{name}')
                any_dampers_off = True
            # each lane labelled on the axis itself, in its colour, at its free (low) level,
            # drawn as a dotted baseline: no label floating away from a flat trace
            ax.axhline(level, color=color, lw=0.6, ls=':', gid=f'lane:{name}')
            ticks.append(level)
            names.append(f'{name} ({100 * frac:.3g} % stuck)' if frac is not None else name)
            level += 1
        ax.set_xlabel('time (s)')
        ax.set_yticks(ticks, names, fontsize=8)
        for label, k in zip(ax.get_yticklabels(), range(len(lanes))):
            label.set_color(colors(k % colors.N))
        ax.set_ylim(-0.3, max(level - 0.2, 0.9))
        # lines only: the labels are on the panels above, here they would cover the lanes
        mark_commands(ax, report.get('commands', ()), labelled=False)
        ax.set_title('stuck state (a lane per impactor: low = free, high = stuck'
                     + (', grey = dampers off)' if any_dampers_off else ')'))
    for ax in axes:   # a log with nothing to plot
        ax.text(0.5, 0.5, 'no sensor, impact or impactor-state topics', ha='center',
                transform=ax.transAxes)
        ax.set_axis_off()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _time_waterfall(fig, ax, s, arrays, commands):
    """A waterfall against time (the speed is held most of the log): frequency up, time
    across, the rotor frequency (1x) dashed and the commands marked."""
    freq, amp = arrays['waterfall_freq_hz'], arrays['waterfall_amp_g']
    times = arrays['waterfall_time_s']
    db = 20 * np.log10(amp + 1e-12)
    top = float(np.nanmax(db)) if db.size else 0.0
    # 80 dB of range, as against speed
    mesh = ax.pcolormesh(times, freq, db.T, shading='nearest', cmap='viridis',
                         vmin=top - 80.0, vmax=top)
    ax.plot(times, arrays['waterfall_speed_rad_s'] / (2 * math.pi), 'w--', lw=0.8, label='1x')
    fig.colorbar(mesh, ax=ax, label='amplitude (dB re 1 g)')
    ax.set_ylim(freq[0], freq[-1])
    ax.set_xlim(times[0], times[-1])
    mark_commands(ax, commands, color='w')
    ax.set_xlabel('time (s)')
    ax.set_ylabel('frequency (Hz)')
    # against time: the speed is held most of the log (a plot against speed would squeeze
    # each held stretch into a thin band)
    ax.set_title(f"waterfall {s['topic']} (speed held: against time)")
    ax.legend(fontsize=8, loc='upper left')


def _command_label(what):
    """A short plot label of a command's text (``'speed 1200 rad/s'``, ``'unbalance x3'``)."""
    return what.split(' (')[0] if what.startswith('speed') else _short(what, 28)


def mark_commands(ax, commands, color='k', labelled=True):
    """Mark each command inside the time axis: a dotted vertical line, labelled at the top
    (unless not ``labelled``).

    Labels that would come closer than 4 % of the axis width to the previous one are left
    out (the text report lists every command).
    """
    lo, hi = ax.get_xlim()
    last = None
    for c in commands:
        t = c['time_s']
        if not lo <= t <= hi:
            continue
        ax.axvline(t, color=color, lw=0.9, ls=':', alpha=0.9)
        if labelled and (last is None or t - last > 0.04 * (hi - lo)):
            ax.text(t, 0.97, ' ' + _command_label(c['what']), transform=ax.get_xaxis_transform(),
                    rotation=90, ha='left', va='top', fontsize=8, color=color)
            last = t


def _short(value, width=70):
    text = ' '.join(str(value).split())
    return text if len(text) <= width else text[:width - 3] + '...'


def impacts_line(imp):
    """The text of an impacts topic: count, mean and peak rate, then each impactor's total.

    The per-impactor numbers are counts over the whole log, not rates: they are labelled so
    (``'peak 54115/s; totals per impactor: imp01 53350, ...'``).
    """
    from .output import fmt as _g
    per = ', '.join(f'{k} {v}' for k, v in imp['per_impactor'].items())
    return (f"\nimpacts {imp['topic']}: {imp['count']} in total, mean "
            f"{_g(imp['mean_rate_hz'])}/s, peak {_g(imp['peak_rate_hz'])}/s"
            + (f'; totals per impactor: {per}' if per else ''))


def print_report(r):
    """Print a report as text (the ``study report`` default output)."""
    from .output import fmt as _g
    from .output import table as _table
    print(f"log {r['file']} (profile {r['profile']}, written by {r['library'] or 'unknown'})")
    print(f"{r['message_count']} messages over {_g(r['duration_s'])} s of log time")
    for name, record in r['metadata'].items():
        print(f'\nmetadata {name}:')
        for key, value in record.items():
            print(f'  {key}: {_short(value)}')
    print()
    print(_table(['topic', 'type', 'count', 'rate (msg/s)', 'frequency (Hz)'],
                 [(t['topic'], t['type'], t['count'], _g(t['rate_hz']), _g(t['frequency_hz']))
                  for t in r['topics']]))
    if r['sensors']:
        print(f"\naccelerations in g (G0 = {G0} m/s^2); times from the first stamp")
        rows = []
        for s in r['sensors']:
            dom = s['spectrum']['dominant_hz']['total'] if s['spectrum'] else None
            rows.append([s['sensor'], s['samples'], _g(s['sample_rate_hz'])]
                        + [_g(s['peak_g'][k], 4) for k in ('x', 'y', 'z', 'magnitude')]
                        + [_g(s['rms_g'][k], 4) for k in ('x', 'y', 'z', 'magnitude')]
                        + [_g(dom, 5)])
        print(_table(['sensor', 'samples', 'fs (Hz)', 'peak x', 'peak y', 'peak z', 'peak |a|',
                      'rms x', 'rms y', 'rms z', 'rms |a|', 'dominant (Hz)'], rows))
        for s in r['sensors']:
            if any(s['nonfinite_samples'].values()):
                print(f"{s['topic']}: {nonfinite_text(s)} (left out of peak and RMS; 'n/a' "
                      'for an axis without a finite sample)')
        for s in r['sensors']:
            w = s['waterfall']
            if w:
                against = ('speed (the speed sweeps)' if w.get('axis') == 'speed' else
                           'time (the speed is held most of the log)')
                print(f"waterfall {s['sensor']}: {w['slices']} slices of {w['segment_samples']}"
                      f" samples ({_g(w['resolution_hz'], 3)} Hz), "
                      f"{_g(min(w['speed_rpm']), 5)} to {_g(max(w['speed_rpm']), 5)} rpm, "
                      f'plotted against {against}')
    for sp in r['rotor_speed']:
        print(f"\nrotor speed {sp['topic']}: {_g(sp['min_rpm'], 5)} to {_g(sp['max_rpm'], 5)} "
              f"rpm ({sp['samples']} samples)")
    for imp in r['impacts']:
        print(impacts_line(imp))
        full = [b for b in imp['bins'] if b['width_s'] >= imp['bin_s'] - 1e-9]
        part = [b for b in imp['bins'] if b['width_s'] < imp['bin_s'] - 1e-9]
        print(f"  impacts/s per full {_g(imp['bin_s'])} s bin: "
              + (' '.join(_g(b['rate_hz'], 4) for b in full[:60]) or 'none')
              + (' ...' if len(full) > 60 else ''))
        for b in part:   # a short last bin is not comparable: its count, not a rate
            print(f"  last {_g(b['width_s'], 3)} s (partial bin): {b['count']} impact(s)")
    if r.get('commands'):
        print('\ncommands (s from the first stamp):')
        for c in r['commands']:
            print(f"  {_g(c['time_s'], 6)} s  {_short(c['what'], 100)}  ({c['topic']})")
    for st in r['impactor_state']:
        print(f"\nstuck fraction ({st['topic']}, time-weighted):")
        print(_table(['impactor', 'stuck fraction', 'stuck (s)', 'observed (s)', 'stick events'],
                     [(name, _g(v['stuck_fraction'], 4), _g(v['stuck_s'], 4),
                       _g(v['observed_s'], 4), v['stick_events'])
                      for name, v in st['impactors'].items()]))


__all__ = ['csv_rows', 'impacts_line', 'plot', 'print_report', 'write_csv']
