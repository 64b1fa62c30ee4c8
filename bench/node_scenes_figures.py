"""The figures of bench/node_scenes.py: one run's data turned into figures, verdict and print-out.

From what the readers left (the node's ``/diagnostics`` windows, every topic's stamps and
arrival times, the Python readers' stamps) and the CPU samples: the real-time factor and CPU
windows, the delivered fractions (:func:`delivered`), the stamp lags against the node's sim
time (:class:`SimClock`, :func:`lag_stats`), whether the monitor kept up (:func:`analyse`),
the verdict against issue 24's goals (:func:`verdict`), the per-scene lines, the summary
table and its markdown page (:func:`page`). Apart from the driver because it runs no process:
it reads arrays and dicts, so it can be checked on recorded data.
"""
from __future__ import annotations

import math
import os
import platform

import numpy as np

NODE_NAME = 'vibration_node'
#: monitor reports received earlier than this after the first sample are not judged (its
#: 2 s window fills, then one report)
MONITOR_WARMUP = 3.5
#: goals of issue 24
RTF_GOAL, CPU_GOAL, DELIVERY_GOAL = 0.98, 60.0, 99.0
#: ... and a cold start (empty Numba cache) to the first sample (s), with ``--cold``
COLD_GOAL = 20.0
SAMPLE_TYPES = ('sensor_msgs/msg/Imu', 'sensor_msgs/msg/PointCloud2')
IMU = 'sensor_msgs/msg/Imu'
PC2 = 'sensor_msgs/msg/PointCloud2'
DIAG = 'diagnostic_msgs/msg/DiagnosticArray'


# ---------------------------------------------------------------------------------------
def _float(text):
    try:
        return float(text)
    except (TypeError, ValueError):
        return math.nan


def _nanmed(values):
    v = [x for x in values if x == x]
    return float(np.median(v)) if v else math.nan


def _nanmax(values):
    v = [x for x in values if x == x]
    return max(v) if v else math.nan


def _nanmin(values):
    v = [x for x in values if x == x]
    return min(v) if v else math.nan


def node_windows(diags, t_lo, t_hi):
    """The node's diagnostics windows received in [t_lo, t_hi], as dicts, in order."""
    out = []
    for t, name, level, message, values in diags:
        # '<fully qualified node name>: simulation', e.g. '/vibration_node: simulation'
        if name.endswith(f'/{NODE_NAME}: simulation') and t_lo <= t <= t_hi:
            w = {k: _float(v) for k, v in values.items()}
            w.update(arrival=t, level=level, message=message)
            out.append(w)
    return out


def counter_windows(windows):
    """(lo, hi, samples, impacts) per pair of consecutive node windows (sim s)."""
    out = []
    for a, b in zip(windows, windows[1:]):
        lo, hi = a.get('sim_time_s', math.nan), b.get('sim_time_s', math.nan)
        if not (hi > lo):
            continue
        sps, ips = b.get('samples_per_s', math.nan), b.get('impacts_per_s', math.nan)
        out.append((lo, hi, round(sps * (hi - lo)) if sps == sps else None,
                    round(ips * (hi - lo)) if ips == ips else None))
    return out


def median_interval(stamps_ns):
    """Median positive interval between sorted distinct stamps (s), and whether regular."""
    s = np.unique(stamps_ns)
    if s.size < 3:
        return math.nan, False
    d = np.diff(s) * 1e-9
    med = float(np.median(d))
    regular = med > 0 and np.mean(np.abs(d - med) <= 0.01 * med) >= 0.9
    return med, bool(regular)


def delivered(stamps_ns, samples, kind, windows, interval, shift=0.0):
    """Delivered fraction (%) of a reader's stream; returns (percent, received, sent).

    ``kind``: 'samples' or 'impacts' (the node's counters over whole windows), 'stamps'
    (span / interval + 1 messages), or None.
    """
    if stamps_ns.size == 0:
        col = {'samples': 2, 'impacts': 3}.get(kind)
        sent = sum(w[col] for w in windows if w[col] is not None) if col else None
        return (0.0 if sent else math.nan), 0, sent
    t = stamps_ns * 1e-9 - shift
    first, last = float(t.min()), float(t.max())
    if kind in ('samples', 'impacts'):
        col = 2 if kind == 'samples' else 3
        inside = [w for w in windows if w[0] >= first - 1e-9 and w[1] <= last + 1e-9
                  and w[col] is not None]
        if not inside:
            return math.nan, 0, None
        lo, hi = inside[0][0], inside[-1][1]
        sent = sum(w[col] for w in inside)
        sel = (t > lo + 1e-9) & (t <= hi + 1e-9)
        got = int(samples[sel].sum()) if samples is not None else int(sel.sum())
        return (100.0 * got / sent if sent else math.nan), got, sent
    if kind == 'stamps' and interval == interval and interval > 0:
        sent = int(round((last - first) / interval)) + 1
        got = int(np.unique(stamps_ns).size)
        return 100.0 * got / sent, got, sent
    return math.nan, int(samples.sum()) if samples is not None else int(stamps_ns.size), None


class SimClock:
    """The node's sim time at a wall instant: the newest stamp the raw reader had received by
    then on a stream published at its stamps' time (``/clock``, the rotor topics, the Imu
    topics), a running maximum over arrival times. One stream alone (``/clock``) reads late
    when the reader was busy with another topic."""

    def __init__(self, streams):
        wall = np.concatenate([w for _, w in streams]) if streams else np.zeros(0)
        sim = np.concatenate([st * 1e-9 for st, _ in streams]) if streams else np.zeros(0)
        order = np.argsort(wall, kind='stable')
        self.wall = wall[order]
        self.sim = np.maximum.accumulate(sim[order]) if wall.size else wall

    def __bool__(self):
        return self.wall.size >= 2

    def __call__(self, wall):
        k = np.searchsorted(self.wall, wall, side='right') - 1
        return np.where(k >= 0, self.sim[np.maximum(k, 0)], np.nan)


def lag_stats(clock, stamps_ns, wall):
    """Max lag (s), p99 and drift (median lag over the last 1 s minus the first 1 s)."""
    if not clock or stamps_ns.size < 2:
        return math.nan, math.nan, math.nan
    inside = wall >= clock.wall[0]
    if not inside.any():
        return math.nan, math.nan, math.nan
    w = wall[inside]
    lag = clock(w) - stamps_ns[inside] * 1e-9
    first = lag[w <= w[0] + 1.0]
    last = lag[w >= w[-1] - 1.0]
    return float(lag.max()), float(np.percentile(lag, 99)), float(np.median(last) -
                                                                  np.median(first))


def analyse(res, meta, arrays, py_out, cpu, node, raw, monitor, t_spawn, t_first, t_stop,
            args):
    """Fill ``res`` with the figures of one run."""
    diags = meta['diagnostics']
    ours = ('bench_raw_reader', 'bench_python_reader_', 'monitor', NODE_NAME)
    res['foreign_nodes'] = [n for n in meta.get('graph_nodes', [])
                            if not n.rsplit('/', 1)[-1].startswith(ours)]
    wins = node_windows(diags, t_spawn, t_stop)
    res['windows'] = len(wins)
    rtf = [w.get('real_time_factor_achieved', math.nan) for w in wins]
    dcpu = [w.get('cpu_percent', math.nan) for w in wins]
    res['rtf_worst'], res['rtf_median'] = _nanmin(rtf), _nanmed(rtf)
    res['rtf_windows'] = rtf
    res['cpu_median'], res['cpu_peak'] = _nanmed(dcpu), _nanmax(dcpu)
    res['samples_per_s'] = _nanmed([w.get('samples_per_s', math.nan) for w in wins])
    cw = counter_windows(wins)
    imp = [w[3] for w in cw if w[3] is not None]
    span = sum(w[1] - w[0] for w in cw if w[3] is not None)
    res['impacts_per_s'] = sum(imp) / span if span > 0 else math.nan
    res['impacts_per_s_peak'] = _nanmax([w.get('impacts_per_s', math.nan) for w in wins])
    res['sim_time_s'] = wins[-1].get('sim_time_s', math.nan) if wins else math.nan
    bad = [w['message'] for w in wins if w['level'] > 0]
    res['node_status'] = 'ok' if not bad else f'{len(bad)} non-OK: {bad[0][:80]}'
    per, mean = cpu.windows(node.pid, t_first, t_stop)
    res['proc_cpu_median'], res['proc_cpu_peak'], res['proc_cpu_mean'] = (
        _nanmed(per), _nanmax(per), mean)
    res['raw_reader_cpu'] = cpu.windows(raw.pid, t_first, t_stop)[1]
    res['raw_reader_drain'] = meta.get('drain')
    res['monitor_cpu'] = cpu.windows(monitor.pid, t_first, t_stop)[1]
    # CPU that other processes (not the bench's, not the --load busy loop) took meanwhile
    with cpu._lock:
        pids = [p for p in cpu.samples if p != 'all']
    ours = sum(x for x in (cpu.windows(p, t_first, t_stop)[1] for p in pids) if x == x)
    res['others_cpu'] = cpu.windows('all', t_first, t_stop)[1] - ours
    node_rate = res['samples_per_s']

    recs = {}
    for m in meta['topics']:
        i = m['index']
        recs[m['topic']] = dict(m, stamps=arrays[f's{i}'], wall=arrays[f'w{i}'],
                                n=arrays[f'n{i}'] if m['type'] == PC2 else None)
    ns_ = (res.get('namespace') or '').rstrip('/')
    timely = {'/clock', f'{ns_}/rotor/speed', f'{ns_}/rotor/joint_states'}
    clock = SimClock([(r['stamps'], r['wall']) for t, r in recs.items()
                      if t in timely or r['type'] == IMU])
    res['topics'] = []
    for name in sorted(recs):
        r = recs[name]
        st, wall = r['stamps'], r['wall']
        row = {'topic': name, 'type': r['type'], 'messages': int(st.size)}
        interval, regular = median_interval(st)
        wspan = float(wall[-1] - wall[0]) if wall.size > 1 else math.nan
        row['messages_per_s'] = (st.size - 1) / wspan if wspan > 0 else math.nan
        samples = r['n'] if r['n'] is not None else None
        nsamp = int(samples.sum()) if samples is not None else int(st.size)
        sim_span = (st.max() - st.min()) * 1e-9 if st.size > 1 else math.nan
        # samples per sim s: the last message's samples lie beyond the span of the stamps
        last = int(samples[np.argmax(st)]) if samples is not None and st.size else 1
        row['samples_per_sim_s'] = (nsamp - last) / sim_span if sim_span > 0 else math.nan
        base = name.rsplit('/', 1)[-1]
        kind = None
        if base == 'impacts' and cw:
            kind = 'impacts'
        elif r['type'] in SAMPLE_TYPES and cw and node_rate == node_rate and \
                abs(row['samples_per_sim_s'] / node_rate - 1.0) < 0.02:
            kind = 'samples'
        elif regular:
            kind = 'stamps'
        row['src'] = {'impacts': 'diag', 'samples': 'diag', 'stamps': 'stamps'}.get(kind, '-')
        # a batch belongs to the window its interval starts in (stamp: the interval's start
        # or its first sample): counted as if stamped half an interval later
        shift = -interval / 2 if r['type'] == PC2 and interval == interval else 0.0
        frac, got, sent = delivered(st, samples, kind, cw, interval, shift)
        row.update(raw_percent=frac, raw_received=got, raw_sent=sent,
                   interval_s=interval, width_check=r.get('width_check'))
        if r['type'] not in (DIAG, 'rcl_interfaces/msg/Log',
                             'rcl_interfaces/msg/ParameterEvent') and clock and st.size:
            row['raw_lag_max'] = float(np.nanmax(clock(wall) - st * 1e-9))
            # stamped ahead of the stream: against what the reader had 20 ms after taking
            # it (a reader back from a stall takes its topics' backlogs one after another)
            row['raw_ahead_max'] = float(np.nanmax(st * 1e-9 - clock(wall + 0.02)))
        p = py_out.get(name)
        if p is not None:
            pst, pw = p['stamps'], p['wall']
            if pst is None or pst.size == 0:
                row.update(py_percent=0.0 if pst is not None else math.nan, py_received=0)
            else:
                frac, got, sent = delivered(pst, None, kind, cw, interval)
                lmax, lp99, drift = lag_stats(clock, pst, pw)
                row.update(py_percent=frac, py_received=got, py_sent=sent,
                           py_lag_max=lmax, py_lag_p99=lp99, py_lag_drift=drift,
                           py_first_sim_s=float(pst.min()) * 1e-9)
            row['py_cpu'] = p['cpu_percent']
            row['py_exit'] = p['exit']
        res['topics'].append(row)

    # the monitor: its sensor rates against the Imu topic's rate (the raw reader's median
    # interval), its impacts in each window against those the raw reader got in that span
    ns = (res.get('namespace') or '').rstrip('/')
    # a sensor's reference rate: of accel/<sensor>/batch (samples per sim s) when the
    # monitor reads that, else of the Imu accel/<sensor> (1 / median interval)
    msubs = set(meta.get('monitor_subscriptions', []))
    res['monitor_subscriptions'] = sorted(msubs)
    rate_of = {}
    for r in res['topics']:
        if r['type'] == IMU and r['interval_s'] == r['interval_s'] and r['interval_s']:
            rate_of.setdefault(r['topic'], 1.0 / r['interval_s'])
        if r['type'] == PC2 and r['topic'] in msubs and r['topic'].endswith('/batch'):
            rate_of[r['topic'][:-len('/batch')]] = r['samples_per_sim_s']
    impacts_rec = next((recs[t] for t in recs if t.rsplit('/', 1)[-1] == 'impacts'), None)
    mon = [(t, name, level, message, values) for t, name, level, message, values in diags
           if name.split(': ', 1)[0].rsplit('/', 1)[-1] == 'monitor']
    judged = [m for m in mon if m[0] >= t_first + MONITOR_WARMUP]
    ratios, problems, ages, impact_ratios, mimp = [], [], [], [], []
    for t, name, level, message, values in judged:
        item = name.split(': ', 1)[1]
        if level:
            problems.append(f'{item}: {message}')
        if 'samples_per_s' in values:
            sensor = item[len(ns) + 1:] if item.startswith(ns + '/') else item
            rate = rate_of.get(f'{ns}/accel/{sensor}')
            if rate:
                ratios.append(_float(values['samples_per_s']) / rate)
            ages.append(_float(values.get('last_sample_age_s')))
        if 'impacts_in_window' in values:
            mimp.append(_float(values.get('impacts_per_s')))
            n, span = _float(values['impacts_in_window']), _float(values.get('span_s'))
            end = _float(values.get('window_end_s'))
            if impacts_rec is not None and span == span and end == end and span > 0:
                st = impacts_rec['stamps'] * 1e-9
                if impacts_rec['n'] is not None:   # batches: at the middle of their interval
                    iv = median_interval(impacts_rec['stamps'])[0]
                    st = st + (iv / 2 if iv == iv else 0.0)
                # what had been published by the report: received before it
                sel = (st > end - span) & (st <= end) & (impacts_rec['wall'] <= t)
                sent = int(impacts_rec['n'][sel].sum()) if impacts_rec['n'] is not None \
                    else int(sel.sum())
                if sent >= 50:
                    impact_ratios.append((n if n == n else 0.0) / sent)
    ok = None if not judged else (not problems and (not ratios or 0.99 <= min(ratios)) and (
        not impact_ratios or min(impact_ratios) >= 0.9))
    res['monitor'] = {
        'reports': len({m[0] for m in judged}), 'ok': ok,
        'problems': sorted(set(problems))[:3], 'problem_count': len(problems),
        'rate_ratio_min': _nanmin(ratios), 'rate_ratio_max': _nanmax(ratios),
        'impacts_ratio_min': _nanmin(impact_ratios),
        'impacts_per_s_median': _nanmed(mimp), 'sample_age_max': _nanmax(ages),
        'statuses': sorted({m[1] for m in mon})}
    verdict(res, args)


def verdict(res, args):
    why = []
    if not res['rtf_worst'] >= RTF_GOAL:
        why.append(f'worst RTF {res["rtf_worst"]:.3f} < {RTF_GOAL}')
    if not res['cpu_peak'] <= CPU_GOAL:
        why.append(f'peak CPU {res["cpu_peak"]:.0f} % > {CPU_GOAL:.0f} %')
    imu = [t for t in res['topics'] if t['type'] == IMU]
    if not imu:
        why.append('no Imu topic read')
    for t in imu:
        if not t.get('py_percent', math.nan) >= DELIVERY_GOAL:
            why.append(f'{t["topic"]}: Python reader {t.get("py_percent", math.nan):.1f} %')
        if not t.get('py_lag_max', math.nan) <= args.lag_limit:
            why.append(f'{t["topic"]}: lag {t.get("py_lag_max", math.nan):.3f} s')
    if res['monitor']['ok'] is None:
        why.append(f'monitor not judged (no report {MONITOR_WARMUP:g} s after the first sample)')
    elif not res['monitor']['ok']:
        why.append('monitor behind')
    if res.get('reason'):
        why.append(res['reason'])
    res['pass'] = not why
    res['why'] = why


# ---------------------------------------------------------------------------------------
def _f(x, fmt, width):
    if x is None or (isinstance(x, float) and x != x):
        return f'{"-":>{width}s}'
    return f'{x:{width}{fmt}}'


def print_scene(res):
    s = res["scene"] + (" (cold start)" if res.get("cold") else "")
    if res.get('first_attempt'):
        print(f'{s}: first attempt: {res["first_attempt"]}')
    if res['status'] != 'ran':
        print(f'{s}: {res["status"]}: {res["reason"]}'
              + (f' (after {res["start_s"]:.1f} s)' if res.get('start_s') else ''))
        for e in res.get('node_errors', []):
            print(f'    node: {e[:150]}')
        return
    m = res['monitor']
    print(f'{s}: start {res["start_s"]:.1f} s, {res["seconds"]:.1f} s run, '
          f'{res["windows"]} diagnostics windows to sim {res["sim_time_s"]:.2f} s; '
          f'RTF worst {res["rtf_worst"]:.3f} median {res["rtf_median"]:.3f}; node CPU % '
          f'median {res["cpu_median"]:.1f} peak {res["cpu_peak"]:.1f} (/proc: median '
          f'{res["proc_cpu_median"]:.1f} peak {res["proc_cpu_peak"]:.1f} mean '
          f'{res["proc_cpu_mean"]:.1f}); {res["samples_per_s"]:.0f} samples/s per '
          f'accelerometer, {res["impacts_per_s"]:.0f} impacts/s (peak window '
          f'{res["impacts_per_s_peak"]:.0f}); status {res["node_status"]}; other processes '
          f'{_f(res["others_cpu"], ".0f", 0)} % of a core, the hypervisor\'s steal '
          f'{_f(res.get("steal_percent", math.nan), ".1f", 0)} % of the CPU time'
          + (' (NOT A QUIET MACHINE)' if res['others_cpu'] > 25
             or res.get('steal_percent', 0) > 2.0 else ''))
    print(f'  {"topic":34s} {"type":15s} {"msg/s":>7s} {"src":>6s} {"raw %":>6s} '
          f'{"raw lag":>7s} {"py %":>6s} {"py CPU":>6s} {"py lag":>6s} {"p99":>6s} '
          f'{"drift":>6s} {"from":>5s}')
    for t in res['topics']:
        print(f'  {t["topic"][:34]:34s} {t["type"].rsplit("/", 1)[-1][:15]:15s} '
              f'{_f(t["messages_per_s"], ".0f", 7)} {t["src"]:>6s} '
              f'{_f(t["raw_percent"], ".1f", 6)} {_f(t.get("raw_lag_max"), ".3f", 7)} '
              f'{_f(t.get("py_percent"), ".1f", 6)} {_f(t.get("py_cpu"), ".0f", 6)} '
              f'{_f(t.get("py_lag_max"), ".3f", 6)} {_f(t.get("py_lag_p99"), ".3f", 6)} '
              f'{_f(t.get("py_lag_drift"), ".3f", 6)} {_f(t.get("py_first_sim_s"), ".2f", 5)}'
              + (f'  width check: {t["width_check"]}' if t.get('width_check') not in
                 (None, 'ok') else ''))

    def pct(x):
        return _f(100.0 * x if x == x else x, '.1f', 0)

    state = {True: 'kept up', False: 'BEHIND', None: 'not judged'}[m['ok']]
    print(f'  monitor: {state} ({m["reports"]} reports judged'
          + (f'; {m["problem_count"]} non-OK, e.g. ' + '; '.join(m['problems'])
             if m['problems'] else '')
          + f'); sample rate {pct(m["rate_ratio_min"])} to {pct(m["rate_ratio_max"])} % of '
          f'its topic\'s, impacts '
          f'>= {pct(m["impacts_ratio_min"])} % of those sent (median '
          f'{_f(m["impacts_per_s_median"], ".0f", 0)}/s), sample age max '
          f'{_f(m["sample_age_max"], ".2f", 0)} s; CPU {_f(res["monitor_cpu"], ".0f", 0)} %; '
          f'raw reader CPU {_f(res["raw_reader_cpu"], ".0f", 0)} %')
    ahead = [f'{t["topic"]} by up to {t["raw_ahead_max"]:.3f} s' for t in res['topics']
             if t.get('raw_ahead_max', 0.0) > 0.005]
    if ahead:
        print('  stamped ahead of the delivered stream (sim time at arrival): ' + ', '.join(ahead))
    if res['node_errors']:
        print('  node errors: ' + ' | '.join(e[:120] for e in res['node_errors']))
    if res['node_warnings']:
        print('  node warnings: ' + ' | '.join(res['node_warnings']))
    if res.get('foreign_nodes'):
        print(f'  other nodes on domain {res["domain"]} (figures may mix): '
              + ', '.join(res['foreign_nodes'][:5]))
    if res.get('node_exit') not in (0, None):
        print(f'  node exit status after SIGINT: {res["node_exit"]}')
    print(f'  verdict: {"PASS" if res["pass"] else "FAIL: " + "; ".join(res["why"])}')


#: the summary table: (heading, width in the print-out, what the column means)
SUMMARY = (
    ('scene', 11, 'the scene (`config/scenes/<scene>.yaml`); `cold`: its run from an empty '
                  'Numba cache (`--cold`), the row after it the same scene warm'),
    ('start s', 7, 'from spawning the node to the first sample (or first node `/diagnostics`) '
                   'the raw reader received (s): imports, loading or compiling the kernels, '
                   'DDS discovery'),
    ('RTF min', 7, 'the worst 1 s window of the node\'s `real_time_factor_achieved` (its '
                   '`/diagnostics`)'),
    ('median', 6, 'the median window of it'),
    ('CPU med', 7, 'the node\'s `cpu_percent` (its process, % of one core), median window'),
    ('peak', 5, 'the same, peak window'),
    ('samples/s', 9, 'samples a second per accelerometer (the node\'s counter)'),
    ('impacts/s', 9, 'impacts per second of sim time over the run'),
    ('py % min', 8, 'the lowest share (%) of the samples sent that a stock Python reader '
                    '(`qos_profile_sensor_data`, one process per `Imu` topic) received'),
    ('py lag', 6, 'the largest stamp lag of that reader (s): the node\'s sim time when a '
                  'sample arrived minus its header stamp'),
    ('py CPU', 6, 'that reader\'s CPU (% of one core, mean over its span)'),
    ('monitor', 7, '`ok`: every report of the monitor from 3.5 s on was OK, read at least 99 % '
                   'of its topic\'s sample rate and 90 % of the impacts; `BEHIND` otherwise; '
                   '`-` not judged'),
    ('verdict', 7, '`PASS` when every goal is met (the reasons are listed under the table)'),
)


def _num(x):
    """A figure read back from JSON (where NaN was written as null) as a float."""
    return math.nan if x is None else x


def summary_cells(r):
    """The summary table's cells of one result (strings, in :data:`SUMMARY`'s order), or
    ``None`` when the scene did not run."""
    if r['status'] != 'ran':
        return None
    imu = [t for t in r['topics'] if t['type'] == IMU]
    return [r['scene'] + (' cold' if r.get('cold') else ''),
            _f(_num(r['start_s']), '.1f', 0), _f(_num(r['rtf_worst']), '.3f', 0),
            _f(_num(r['rtf_median']), '.3f', 0), _f(_num(r['cpu_median']), '.1f', 0),
            _f(_num(r['cpu_peak']), '.1f', 0), _f(_num(r['samples_per_s']), '.0f', 0),
            _f(_num(r['impacts_per_s']), '.0f', 0),
            _f(_nanmin([_num(t.get('py_percent')) for t in imu]), '.1f', 0),
            _f(_nanmax([_num(t.get('py_lag_max')) for t in imu]), '.3f', 0),
            _f(_nanmax([_num(t.get('py_cpu')) for t in imu]), '.0f', 0),
            {True: 'ok', False: 'BEHIND', None: '-'}[r['monitor']['ok']],
            'PASS' if r['pass'] else 'FAIL']


def print_table(results):
    print()
    print(' '.join(f'{h:{w}s}' if i == 0 else f'{h:>{w}s}'
                   for i, (h, w, _) in enumerate(SUMMARY)))
    for r in results:
        cells = summary_cells(r)
        if cells is None:
            name = r['scene'] + (' cold' if r.get('cold') else '')
            print(f'{name:11s} {r["status"]}: {r["reason"]}')
            continue
        print(' '.join(f'{c:{w}s}' if i == 0 else f'{c:>{w}s}'
                       for i, (c, (_, w, _)) in enumerate(zip(cells, SUMMARY))))


def machine():
    """This machine in words: CPU model and core count."""
    try:
        with open('/proc/cpuinfo') as fh:
            model = next((line.split(':', 1)[1].strip() for line in fh
                          if line.startswith('model name')), '')
    except OSError:
        model = ''
    cores = os.cpu_count() or 0
    return f'{model or platform.machine()}, {cores} core{"s" if cores != 1 else ""}'


def page(data):
    """A markdown page of a run's results (what ``--json`` writes: date, machine, command,
    load, results): the header once, the summary table, the verdicts, the machine's state
    per scene and what each column means."""
    def said(key, fmt='', missing='not recorded'):
        value = data.get(key)
        return missing if value is None else f'{value:{fmt}}'

    results = data['results']
    lines = [
        '# vibration_node on every shipped scene: measured',
        '',
        '<!-- written by bench/node_scenes.py --page; do not edit: run it again -->',
        '',
        f'- **Date**: {said("date")}',
        f'- **Machine**: {said("machine")}',
        f'- **Command**: `{said("command")}` ({said("seconds", "g")} s per scene from the '
        'first sample)',
        f'- **Load** (1-min average): {said("load_before", ".2f")} before, '
        f'{said("load", ".2f")} after; '
        + ('a busy loop pinned to the last core during every run (`--load`)'
           if data.get('load_hog') else 'no added load'),
        '',
        'What is measured and the goals: [node.md](../node.md#performance); every figure '
        'below, and how it is taken, in `bench/node_scenes.py`\'s docstring.',
        '',
        '| ' + ' | '.join(h for h, _, _ in SUMMARY) + ' |',
        '|' + '---|' * len(SUMMARY),
    ]
    for r in results:
        cells = summary_cells(r)
        if cells is None:
            name = r['scene'] + (' cold' if r.get('cold') else '')
            cells = [name, f'{r["status"]}: {r.get("reason", "")}'.replace('|', '\\|')] + \
                [''] * (len(SUMMARY) - 2)
        lines.append('| ' + ' | '.join(cells) + ' |')
    lines += ['', '**Verdicts** (goals: worst 1 s window >= '
              f'{RTF_GOAL}, peak window CPU <= {CPU_GOAL:.0f} % of a core, every Python '
              f'`Imu` reader >= {DELIVERY_GOAL:.0f} % with its lag under the limit, the '
              f'monitor kept up; a cold start <= {COLD_GOAL:g} s):', '']
    for r in results:
        name = r['scene'] + (' (cold start)' if r.get('cold') else '')
        if r['status'] != 'ran':
            lines.append(f'- {name}: {r["status"]}: {r.get("reason", "")}')
        else:
            lines.append(f'- {name}: ' + ('PASS' if r['pass'] else
                                          'FAIL: ' + '; '.join(r.get('why', []))))
    ran = [r for r in results if r['status'] == 'ran']
    if ran:
        lines += ['', 'The machine during each scene (over 25 % of a core taken by other '
                  'processes, or over 2 % of the CPU time stolen by the hypervisor, is not a '
                  'quiet machine):', '',
                  '| scene | other processes, % of a core | hypervisor\'s steal, % |',
                  '|---|---|---|']
        for r in ran:
            lines.append(f'| {r["scene"] + (" cold" if r.get("cold") else "")} | '
                         f'{_f(_num(r.get("others_cpu")), ".0f", 0)} | '
                         f'{_f(_num(r.get("steal_percent")), ".1f", 0)} |')
    lines += ['', '## What the columns mean', '']
    lines += [f'- **{h}**: {meaning}' for h, _, meaning in SUMMARY]
    return '\n'.join(lines) + '\n'


def _jsonable(x):
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return None if x != x else float(x)
    if isinstance(x, np.integer):
        return int(x)
    return x
