"""The accelerometer channel's CPU cost against the node's stepping cost (issue 36, item 7).

Goal (issue 36): the whole chain within 10 % of the node's CPU on rbs (20 kHz: one triaxial
accelerometer, integrator and output at 20 kHz, Imu at 1 kHz). Measured in one process and one
run, CPU time of the stepping thread (``time.thread_time``; OpenBLAS held to one thread), in
the node's 10 ms chunks, after a warm-up:

1. **Stepping**: ``LiveSimulation.step`` CPU per sim second with the scene's own preset and with
   ``channel=ideal`` (a scene override), ``--repeat`` blocks of ``--seconds`` sim seconds each,
   the two alternating (A B, B A, ...) so that a change in the machine's load falls on both;
   the median and the spread (min to max) of each, and of the chain's added cost, taken per
   repetition as ``preset - ideal``: in ms per sim second, as a share of the ideal stepping
   (what the chain adds) and of the stepping with it (what share of it the chain is).
2. **The chain in place**: ``SensorChannel.process`` (full rate) and ``process_decimated`` (the
   Imu's re-quantization) timed inside ``LiveSimulation.step``, per accelerometer, in separate
   blocks (the timers' own cost stays out of 1.).
3. **Per stage**: ``SensorChannel.process`` alone on the scene's recorded input (the model's
   mean acceleration per step, 1 s of it in the same chunks), the preset's stages switched on
   one at a time in the chain's order, the cost each adds (median of ``--repeat``).

The ideal channel is not free: it is the anti-alias low-pass and the pick that ``LiveSimulation``
ran before the channel existed; "chain" is what the preset adds to it. The node spends more
than the stepping (serialization, publishing, DDS: ``bench/node_realtime.py`` sets the node
against the bare stepping), so the share of the whole node's CPU is smaller than the share
printed here. CPU figures depend on the machine and its load, printed in the header: compare
the ratios, which are measured in the same run. Usage::

    .venv/bin/python bench/channel_cost.py [--scene rbs] [--seconds 10] [--repeat 7]
"""
from __future__ import annotations

import argparse
import datetime
import os
import platform
import time

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')

import numpy as np  # noqa: E402

from impact_damper_sim.live.channel import SensorChannel  # noqa: E402
from impact_damper_sim.live.realtime import LiveSimulation  # noqa: E402
from impact_damper_sim.live.streams import live_scene  # noqa: E402

GOAL = 0.10   # issue 36: the chain within 10 % of the stepping
#: Stage groups in the chain's order: (label, spec keys switched on together).
STAGE_GROUPS = (
    # the first stage on also starts the chain's own path beside the truth's (6 columns
    # through the low-pass instead of 3): its cost is in this row
    ('mounting, and the truth path beside the chain', ('orientation', 'transverse',
                                                       'sensitivity_error')),
    ('resonance', ('resonance',)),
    ('highpass', ('highpass',)),
    ('sensor noise and bias (noise_density, bias)', ('noise_density', 'bias')),
    ('range clip', ('range',)),
    ('ADC (noise, clip, grid)', ('adc', 'sensitivity')),
)


def machine():
    """One line: CPU model, cores, load average now."""
    model = platform.processor() or platform.machine()
    try:
        with open('/proc/cpuinfo') as f:
            model = next(line.split(':', 1)[1].strip() for line in f
                         if line.startswith('model name'))
    except (OSError, StopIteration):
        pass
    usable = len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else '?'
    load = ' '.join(f'{v:.2f}' for v in os.getloadavg())
    return (f'CPU {model}, {os.cpu_count()} cores ({usable} usable), load average '
            f'(1/5/15 min) {load}')


def make(scene, overrides, seed, warmup):
    """A LiveSimulation of the scene, its kernels loaded and ``warmup`` sim seconds stepped."""
    model, target = live_scene(scene, overrides)
    live = LiveSimulation(model, initial_target=target, seed=seed)
    chunk = max(1, round(0.01 * live.sample_rate))   # the node's 10 ms tick
    while live.t < warmup - 1e-9:
        live.step(chunk)
    return live, chunk


def stepping(live, chunk, seconds):
    """CPU (s) per sim second of ``LiveSimulation.step`` over ``seconds`` of sim time."""
    t0, c0 = live.t, time.thread_time()
    while live.t - t0 < seconds - 1e-9:
        live.step(chunk)
    return (time.thread_time() - c0) / (live.t - t0)


def in_place(live, chunk, seconds):
    """CPU (s) per sim second of each channel's process + process_decimated inside step."""
    spent = [0.0] * len(live.channels)

    def timed(k, method):
        def call(*args, **kwargs):
            c = time.thread_time()
            try:
                return method(*args, **kwargs)
            finally:
                spent[k] += time.thread_time() - c
        return call

    for k, ch in enumerate(live.channels):
        ch.process = timed(k, ch.process)
        ch.process_decimated = timed(k, ch.process_decimated)
    t0 = live.t
    try:
        while live.t - t0 < seconds - 1e-9:
            live.step(chunk)
    finally:
        for ch in live.channels:   # back to the class's methods
            del ch.process, ch.process_decimated
    return [s / (live.t - t0) for s in spent]


def recorded_input(live, chunk, seconds=1.0):
    """The first channel's input (mean acceleration per step), chunk by chunk, for ``seconds``."""
    ch, chunks = live.channels[0], []
    process = ch.process

    def keep(mean_acc, **kwargs):
        chunks.append(np.array(mean_acc))
        return process(mean_acc, **kwargs)

    ch.process = keep
    t0 = live.t
    try:
        while live.t - t0 < seconds - 1e-9:
            live.step(chunk)
    finally:
        del ch.process
    return chunks, live.t - t0


def per_stage(live, chunks, span, repeat):
    """Rows (label, CPU s per sim second, added s per sim second) with stages added in order."""
    ch = live.channels[0]
    spec = ch.spec
    kwargs = dict(step_rate_hz=ch.step_rate_hz, decimation=ch.decimation,
                  lowpass_hz=ch.lowpass_hz, seed=ch.seed, name=ch.name)
    on = {k: None for k in spec}
    on['preset'] = spec['preset']
    rows = []

    def cost():
        times = []
        for _ in range(repeat):
            channel = SensorChannel(dict(on), **kwargs)
            channel.process(chunks[0][:0])   # kernels loaded, as in the node's warm-up
            c0 = time.thread_time()
            for x in chunks:
                channel.process(x)
            times.append((time.thread_time() - c0) / span)
        return float(np.median(times))

    last = cost()
    rows.append(('ideal channel (anti-alias low-pass and pick)', last, None))
    for label, keys in STAGE_GROUPS:
        if all(spec[k] is None for k in keys if k != 'sensitivity'):
            rows.append((label, None, None))   # off in this preset
            continue
        for k in keys:
            on[k] = spec[k]
        now = cost()
        rows.append((label, now, now - last))
        last = now
    return rows


def _ms(v):
    return f'{1e3 * v:7.2f}'


def _spread(values, scale=1e3, fmt='{:.2f}'):
    values = np.asarray(values) * scale
    return (f'{fmt.format(np.median(values))} [{fmt.format(values.min())} .. '
            f'{fmt.format(values.max())}]')


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--scene', default='rbs', help='scene name or file (default rbs)')
    parser.add_argument('--seconds', type=float, default=10.0,
                        help='sim seconds per timed block (default 10)')
    parser.add_argument('--repeat', type=int, default=7, help='repetitions (default 7)')
    parser.add_argument('--warmup', type=float, default=0.5,
                        help='sim seconds stepped before timing (default 0.5)')
    parser.add_argument('--seed', type=int, default=0, help='noise_seed (default 0)')
    args = parser.parse_args(argv)

    print(f'channel_cost: {datetime.date.today().isoformat()}, {machine()}')
    preset, chunk = make(args.scene, (), args.seed, args.warmup)
    ideal, _ = make(args.scene, ('channel=ideal',), args.seed, args.warmup)
    accs = preset.accelerometers
    names = ', '.join(f"{a.name} ({ch.spec['preset']})" for a, ch in zip(accs, preset.channels))
    ch0 = preset.channels[0]
    print(f'scene {args.scene}: {len(accs)} accelerometer(s): {names}; integrator '
          f'{1 / preset.dt:g} Hz, output {preset.sample_rate:g} Hz (decimation '
          f'{preset.decimation}), Imu {preset.imu_rate:g} Hz; chunks of {chunk} samples '
          f'(10 ms); resonance latency {ch0.delay_steps} steps')
    print(f'{args.repeat} repetitions of {args.seconds:g} sim s each, after {args.warmup:g} s '
          'of warm-up; CPU of the stepping thread; median [min .. max]\n')

    cases = {'preset': preset, 'ideal': ideal}
    step = {k: [] for k in cases}
    for r in range(args.repeat):
        for key in (('preset', 'ideal') if r % 2 == 0 else ('ideal', 'preset')):
            step[key].append(stepping(cases[key], chunk, args.seconds))
    inside = {k: [] for k in cases}
    for r in range(args.repeat):
        for key in (('preset', 'ideal') if r % 2 == 0 else ('ideal', 'preset')):
            inside[key].append(in_place(cases[key], chunk, args.seconds))

    p, i = np.array(step['preset']), np.array(step['ideal'])
    added = p - i
    print('1. LiveSimulation.step, CPU ms per sim second (/ 10 = % of one core at real time)')
    print(f'   preset {ch0.spec["preset"]:<16} {_spread(p)}')
    print(f'   channel=ideal           {_spread(i)}')
    print(f'   chain (preset - ideal)  {_spread(added)}')
    print(f'   chain / ideal stepping  {_spread(added / i, 100, "{:.1f}")} %   '
          f'(what the chain adds; goal <= {100 * GOAL:g} %)')
    print(f'   chain / preset stepping {_spread(added / p, 100, "{:.1f}")} %   '
          '(its share of the stepping with it)\n')

    print('2. The chain in place (process + process_decimated inside step), CPU ms per sim '
          'second')
    ins_p = np.array(inside['preset'])   # (repeat, n_acc)
    ins_i = np.array(inside['ideal'])
    for k, acc in enumerate(accs):
        print(f'   {acc.name}: preset {_spread(ins_p[:, k])}, ideal {_spread(ins_i[:, k])}, '
              f'added {_spread(ins_p[:, k] - ins_i[:, k])}')
    total = ins_p.sum(axis=1) - ins_i.sum(axis=1)
    print(f'   all accelerometers, added: {_spread(total)} = '
          f'{_spread(total / np.median(i), 100, "{:.1f}")} % of the ideal stepping\n')

    chunks, span = recorded_input(preset, chunk)
    rows = per_stage(preset, chunks, span, args.repeat)
    print(f'3. Per stage, SensorChannel.process alone on {span:g} s of {accs[0].name}\'s '
          f'recorded input (median of {args.repeat}); CPU ms per sim second. A tight loop:\n'
          '   less than in place (2.), where the engine shares the caches')
    print(f'   {"stages on, in the chain order":<58} {"total":>7} {"added":>7} '
          f'{"% of ideal stepping":>20}')
    for label, value, extra in rows:
        if value is None:
            print(f'   + {label:<56} {"off in this preset":>16}')
            continue
        share = '' if extra is None else f'{100 * extra / np.median(i):19.1f} %'
        lead = '  ' if extra is None else '+ '
        print(f'   {lead}{label:<56} {_ms(value)} '
              f'{"" if extra is None else _ms(extra):>7} {share}')
    share = np.median(added / i)
    verdict = 'met' if share <= GOAL else 'NOT met'
    print(f'\ngoal (issue 36, item 7): the chain adds {100 * share:.1f} % to the stepping of '
          f'{args.scene} (median); within {100 * GOAL:g} %: {verdict}')
    load = ' '.join(f'{v:.2f}' for v in os.getloadavg())
    print(f'load average at the end (1/5/15 min): {load}')


if __name__ == '__main__':
    main()
