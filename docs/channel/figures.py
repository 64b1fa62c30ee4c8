"""Draw the figures of docs/channel.md: the accelerometer chain, and hpotp's ground truth
against its channel output (time trace and PSD).

Run from the repository root::

    AMENT_PREFIX_PATH=$PWD/.venv .venv/bin/python docs/channel/figures.py [--out docs/channel]

It writes ``chain.png``, ``hpotp_trace.png`` and ``hpotp_psd.png`` (800 px wide at 100 dpi,
text 8 pt or more, as ``impact_damper_sim/studies/plot_style.py`` asks of every plot). The
run is deterministic: ``LiveSimulation`` with ``seed=0`` and ``noise_std=0`` (the channel's own
noise only), stepped in the node's 10 ms chunks; the same software gives the same PNGs.

hpotp is stepped from rest under its scene preset (``iepe_10mv_500g``) for 12 s of sim time:
the rotor reaches full speed (2400 rad/s) at 5 s; the trace shows 20 ms from 6 s, the PSD
(Welch) 6 s from 6 s. About 2 s of CPU.
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')

import numpy as np  # noqa: E402

from impact_damper_sim.live.realtime import LiveSimulation  # noqa: E402
from impact_damper_sim.live.streams import live_scene  # noqa: E402
from impact_damper_sim.scene.units import G0  # noqa: E402

SEED = 0
T_END = 12.0                 # s of sim time stepped
TRACE = (6.0, 6.02)          # s: the time trace's window (full speed)
PSD_FROM = 6.0               # s: the PSD's span starts here and runs to T_END
NPERSEG = 1024               # Welch segment (samples at the output rate: 0.51 s, 1.95 Hz)
DPI = 100
WIDTH_IN = 8.0               # 800 px at DPI
PNG_META = {'Software': None}   # no version string in the file: same bytes on every run

# colours (Okabe-Ito, distinct for colour-blind readers)
C_TRUTH, C_OUT, C_DIFF, C_X, C_STEP = 'black', '#D55E00', '#CC79A7', '#0072B2', '#999999'


def simulate():
    """Step hpotp with its preset; return what the figures need (SI, output rate)."""
    model, target = live_scene('hpotp')
    live = LiveSimulation(model, initial_target=target, noise_std=0.0, seed=SEED)
    channel = live.channels[0]
    chunk = round(0.01 * live.sample_rate)   # the node's 10 ms tick
    steps = []   # (step end times, mean acceleration per step) in the trace window
    process = channel.process

    def keep_input(mean_acc, **hooks):   # the chain's input: the model's mean acc. per step
        n = len(mean_acc)
        t = t_before[0] + live.dt * np.arange(1, n + 1)
        if t[-1] >= TRACE[0] - 0.01 and t[0] <= TRACE[1] + 0.01:
            steps.append((t, np.array(mean_acc)))
        return process(mean_acc, **hooks)

    channel.process = keep_input
    t_before = [live.t]
    ts, out, truth, impacts = [], [], [], []
    while live.t < T_END - 1e-9:
        t_before[0] = live.t
        batch = live.step(chunk)
        ts.append(batch.t)
        out.append(batch.linear_acceleration[:, 0])
        truth.append(batch.truth[:, 0])
        ev = batch.events
        impacts.append(ev['t'][ev['kind'] == 0])
    speed = live.rotor_state()[0]
    return dict(
        t=np.concatenate(ts), out=np.concatenate(out), truth=np.concatenate(truth),
        impacts=np.concatenate(impacts),
        step_t=np.concatenate([s[0] for s in steps]),
        step_a=np.concatenate([s[1] for s in steps]),
        fs=live.sample_rate, step_rate=1.0 / live.dt, delay_s=channel.delay_s,
        delay_steps=channel.delay_steps, lowpass=live.accelerometers[0].lowpass_hz,
        variance=channel.output_noise_variance(), preset=channel.spec['preset'],
        name=live.accelerometers[0].name, shaft_hz=speed / (2.0 * np.pi))


def _style():
    import matplotlib
    matplotlib.use('Agg')
    matplotlib.rcParams.update({'font.size': 10, 'axes.titlesize': 10, 'legend.fontsize': 9,
                                'xtick.labelsize': 9, 'ytick.labelsize': 9,
                                'axes.grid': True, 'grid.alpha': 0.3})
    import matplotlib.pyplot as plt
    return plt


def draw_chain(path):
    """The block diagram: stages in order, the rates they run at, the truth and Imu branches."""
    plt = _style()
    from matplotlib.patches import FancyBboxPatch
    fig = plt.figure(figsize=(WIDTH_IN, 9.0), dpi=DPI)
    ax = fig.add_axes([0, 0, 1, 1])
    ax.set_xlim(0, 80)
    ax.set_ylim(0, 90)
    ax.axis('off')

    def box(x, y, w, h, text, face='white', weight='normal'):
        ax.add_patch(FancyBboxPatch((x, y), w, h, boxstyle='round,pad=0.3,rounding_size=0.8',
                                    fc=face, ec='black', lw=1.0))
        ax.text(x + w / 2, y + h / 2, text, ha='center', va='center', fontsize=9,
                weight=weight, linespacing=1.25)

    def arrow(x0, y0, x1, y1, color='black', style=None):
        props = dict(arrowstyle='-|>', lw=1.0, color=color, shrinkA=0, shrinkB=0)
        if style:
            props['connectionstyle'] = style
        ax.annotate('', xy=(x1, y1), xytext=(x0, y0), arrowprops=props)

    x, w, gap = 17.0, 36.0, 2.2            # main column
    rx, rw = 57.0, 21.0                    # right column
    main = [   # (text, band, face, bold)
        ('model: mean acceleration per step\n(model frame, no gravity)', 'step', 'white', True),
        ('1  mounting  M = S (I + T) R^T\norientation, transverse, sensitivity_error',
         'step', 'white', False),
        ('2  mounted resonance (fn, Q): resonance\ncausal biquads, no latency',
         'step', 'white', False),
        ('3  IEPE high-pass, first order\nhighpass (corner or time_constant)', 'step',
         'white', False),
        ('4  + sensor noise and bias\nnoise_density; bias (turn_on,\n'
         'gauss_markov, random_walk)', 'step', 'white', False),
        ('5  anti-alias low-pass\nsensors[].lowpass, 4th-order Butterworth', 'step',
         'white', False),
        ('6  pick every decimation-th step\n(hpotp 5, rbs 1)', 'out', 'white', False),
        ('7  + live white noise (noise_std)\n8  clip at +-range (counted)', 'out', 'white',
         False),
        ('9  + DAQ noise (adc.noise)\n10 ADC: clip at +-full_scale (counted),\n'
         'round to the LSB grid', 'out', 'white', False),
        ('accel/<name>/batch\n(Batch.linear_acceleration, sensor frame)', 'out', '#FFF7D6',
         False),
        ('decimation FIR (StreamingDecimator)\nfrom sample_rate to imu_rate\n(80 dB anti-alias)',
         'imu', 'white', False),
    ]
    heights = [4.6 + 1.9 * (text.count('\n') - 1) for text, *_ in main]
    tops, y = [], 84.0
    for h in heights:
        tops.append(y)
        y -= h + gap
    rows = [(top - h, h) for top, h in zip(tops, heights)]   # (bottom, height)

    # rate bands behind the boxes, from the boxes they hold
    colors = {'step': '#E8F1FA', 'out': '#FDF1E6', 'imu': '#EEF6EC'}
    labels = {'step': 'step rate 1/dt\n(hpotp 10 kHz,\nrbs 20 kHz)',
              'out': 'output rate\nsample_rate\n(hpotp 2 kHz,\nrbs 20 kHz)',
              'imu': 'imu_rate\n(1 kHz)'}
    for band in ('step', 'out', 'imu'):
        idx = [i for i, m in enumerate(main) if m[1] == band]
        y0 = rows[idx[-1]][0] - gap / 2
        y1 = rows[idx[0]][0] + rows[idx[0]][1] + gap / 2
        ax.add_patch(FancyBboxPatch((0.8, y0 + 0.15), 78.4, y1 - y0 - 0.3,
                                    boxstyle='round,pad=0.1', fc=colors[band], ec='none'))
        ax.text(2.0, (y0 + y1) / 2, labels[band], ha='left', va='center', fontsize=9,
                style='italic', color='#333333', linespacing=1.2)
    for (text, _, face, bold), (bottom, h) in zip(main, rows):
        box(x, bottom, w, h, text, face=face, weight='bold' if bold else 'normal')
    for (b0, _), (b1, h1) in zip(rows, rows[1:]):
        arrow(x + w / 2, b0, x + w / 2, b1 + h1)

    # the Imu output, right of the FIR
    fb, fh = rows[-1]
    box(rx, fb, rw, fh, 'clip at +-range, round\nto the grid: accel/<name>\n'
        '(sensor_msgs/Imu)', face='#FFF7D6')
    arrow(x + w, fb + fh / 2, rx, fb + fh / 2)

    # the ground-truth branch, level with the stages it shares
    def level(i):
        return rows[i][0], rows[i][1]
    truth = [(5, 'the same\nanti-alias low-pass'),
             (6, 'the same pick'), (7, 'Batch.truth\n(model frame)')]
    grey = '#555555'
    for k, (i, text) in enumerate(truth):
        b, h = level(i)
        box(rx, b, rw, h, text, face='#F2F2F2')
        if k:
            pb, _ = level(truth[k - 1][0])
            arrow(rx + rw / 2, pb, rx + rw / 2, b + h, color=grey)
    mb, mh = rows[0]
    b2, h2 = level(truth[0][0])
    arrow(x + w, mb + mh / 2, rx + rw / 2, b2 + h2, color=grey,
          style='angle,angleA=0,angleB=90,rad=0')
    ax.text(rx + rw / 2, 86.2, 'ground truth', ha='center', va='bottom', fontsize=9,
            weight='bold', color='#333333')
    ax.text(x + w / 2, 86.2, 'the channel, in order (each stage off when not given)',
            ha='center', va='bottom', fontsize=9, weight='bold')
    bottom = min(b for b, _ in rows) - 2.0
    ax.set_ylim(bottom, 90)
    fig.set_size_inches(WIDTH_IN, 9.0 * (90 - bottom) / 90)
    fig.savefig(path, dpi=DPI, metadata=PNG_META)
    plt.close(fig)


def draw_trace(d, path):
    """20 ms at full speed: the model's step-rate input, truth against output, their difference."""
    plt = _style()
    lo, hi = TRACE
    fig, axes = plt.subplots(3, 1, figsize=(WIDTH_IN, 7.6), dpi=DPI, sharex=True,
                             gridspec_kw={'height_ratios': [1.0, 1.25, 1.0]})
    ms = 1e3

    def window(t):
        return (t >= lo - 1e-9) & (t <= hi + 1e-9)

    s = window(d['step_t'])
    ax = axes[0]
    a = d['step_a'][s, 1] / G0
    ax.plot((d['step_t'][s] - lo) * ms, a, color=C_STEP, lw=1.0,
            label=f"model, mean per integrator step ({d['step_rate'] / 1e3:g} kHz)")
    imp = d['impacts'][window(d['impacts'])]
    peak = np.max(np.abs(a))
    ax.plot((imp - lo) * ms, np.full(imp.shape, -1.3 * peak), '|', color=C_X,
            ms=8, mew=1.0, label=f'impacts ({imp.size} in {1e3 * (hi - lo):g} ms)')
    ax.set_ylim(-1.5 * peak, 1.75 * peak)
    ax.set_ylabel('y  (g)')
    ax.legend(loc='upper right', ncol=2, framealpha=0.9)
    ax.set_title(f"hpotp at full speed ({d['shaft_hz']:.0f} Hz shaft), accelerometer "
                 f"{d['name']}, preset {d['preset']}", loc='left')

    s = window(d['t'])
    t = (d['t'][s] - lo) * ms
    ax = axes[1]
    ax.plot(t, d['truth'][s, 1] / G0, '-o', color=C_TRUTH, ms=3.0, lw=1.2,
            label='ground truth (Batch.truth)')
    ax.plot(t, d['out'][s, 1] / G0, 'x', color=C_OUT, ms=6.0, mew=1.3,
            label='channel output (Batch.linear_acceleration)')
    peak = np.max(np.abs(d['truth'][s, 1])) / G0
    ax.set_ylim(-1.15 * peak, 1.75 * peak)
    ax.set_ylabel('y  (g)')
    ax.legend(loc='upper right', ncol=2, framealpha=0.9)

    ax = axes[2]
    sigma = np.sqrt(d['variance']) / G0 * 1e3
    ax.axhspan(-sigma, sigma, color=C_OUT, alpha=0.12, lw=0,
               label=f'+-1 sigma of the white noise ({sigma:.1f} mg)')
    ax.plot(t, (d['out'][s, 1] - d['truth'][s, 1]) / G0 * 1e3, '-x', color=C_OUT, ms=5,
            lw=1.0, label='y: output - truth (2 % of z + noise)')
    ax.plot(t, (d['out'][s, 0] - d['truth'][s, 0]) / G0 * 1e3, '-+', color=C_X, ms=6,
            lw=1.0, label='x: output (2 % of y + noise; no x in the model)')
    lim = 1.1 * max(np.max(np.abs(ax.get_ylim())), 4 * sigma)
    ax.set_ylim(-lim, 1.6 * lim)
    ax.set_ylabel('output - truth  (mg)')
    ax.set_xlabel(f'sim time after {lo:g} s  (ms)')
    ax.legend(loc='upper left', ncol=2, framealpha=0.9)
    ax.set_xlim(0, (hi - lo) * ms)
    fig.align_ylabels(axes)
    fig.tight_layout(h_pad=0.6)
    fig.savefig(path, dpi=DPI, metadata=PNG_META)
    plt.close(fig)


def draw_psd(d, path):
    """Welch PSD over 6 s at full speed, log-log: truth, output, their difference, the floor."""
    from matplotlib.ticker import FuncFormatter
    from scipy.signal import welch

    from impact_damper_sim.studies.plot_style import log_ticks
    plt = _style()
    s = d['t'] >= PSD_FROM - 1e-9
    fs = d['fs']

    def psd(x):
        f, p = welch(x / G0, fs=fs, window='hann', nperseg=NPERSEG, noverlap=NPERSEG // 2,
                     detrend='constant', scaling='density')
        return f[1:], p[1:]

    f, p_truth = psd(d['truth'][s, 1])
    _, p_out = psd(d['out'][s, 1])
    _, p_diff = psd(d['out'][s, 1] - d['truth'][s, 1])
    _, p_x = psd(d['out'][s, 0])
    floor = d['variance'] / G0 ** 2 / (fs / 2)
    fig, ax = plt.subplots(figsize=(WIDTH_IN, 5.4), dpi=DPI)
    ax.loglog(f, p_truth, color=C_TRUTH, lw=1.6, label='y: ground truth (Batch.truth)')
    ax.loglog(f, p_out, color=C_OUT, lw=1.0, label='y: channel output')
    ax.loglog(f, p_diff, color=C_DIFF, lw=1.0, label='y: output - truth')
    ax.loglog(f, p_x, color=C_X, lw=1.0, alpha=0.8,
              label='x: channel output (no x motion in the model)')
    ax.axhline(floor, color='black', ls='--', lw=1.0,
               label=f'white noise: variance / (fs/2) = ({np.sqrt(d["variance"]) / G0 * 1e3:.1f}'
                     f' mg)^2 / {fs / 2e3:g} kHz')
    ax.axvline(d['lowpass'], color='#555555', ls=':', lw=1.0)
    ax.axvline(d['shaft_hz'], color='#555555', ls=':', lw=1.0)
    lo = max(min(p_truth.min(), p_diff.min(), p_x.min(), floor) * 0.5, 1e-14)
    hi = max(p_truth.max(), p_out.max()) * 3
    log_ticks(ax.xaxis, f[0], fs / 2)
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f'{v:g}'))   # 2, 5, 10, ...
    log_ticks(ax.yaxis, lo, hi)
    top = ax.get_ylim()[1]
    ax.text(d['shaft_hz'] * 0.95, top / 3, f"1x shaft\n{d['shaft_hz']:.0f} Hz", ha='right',
            va='top', fontsize=9, color='#333333')
    ax.text(d['lowpass'] * 0.97, top / 3e3, f"anti-alias\n{d['lowpass']:g} Hz", ha='right',
            va='top', fontsize=9, color='#333333')
    ax.set_xlabel('frequency  (Hz)')
    ax.set_ylabel('PSD  (g^2/Hz)')
    ax.set_title(f"hpotp at full speed, Welch over {T_END - PSD_FROM:g} s "
                 f"({NPERSEG} samples, Hann, 50 % overlap), preset {d['preset']}", loc='left')
    ax.legend(loc='upper left', framealpha=0.9)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI, metadata=PNG_META)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--out', default=str(Path(__file__).resolve().parent),
                        help='directory of the PNGs (default: this script\'s)')
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    draw_chain(out / 'chain.png')
    d = simulate()
    draw_trace(d, out / 'hpotp_trace.png')
    draw_psd(d, out / 'hpotp_psd.png')
    for name in ('chain.png', 'hpotp_trace.png', 'hpotp_psd.png'):
        print(out / name)


if __name__ == '__main__':
    main()
