#!/usr/bin/env python3
"""Compile the Numba kernels every shipped scene uses into the per-user cache, once.

`make` runs this as the last step of its set-up (the ``.venv/.kernels`` rule, again whenever a
kernel source changes), so that the first ``make run`` or ``ros2 run impact_damper_sim
vibration_node`` after it starts in about 2 s instead of compiling for 20-40 s, as ``pip``
compiles ``.pyc`` files at install time. Nothing here is needed for correctness: a run with
an empty cache compiles what it calls (``NUMBA_CACHE_DIR``: where; ``docs/node.md``: how long).

For each scene in ``config/scenes``: the node's warm-up (``LiveSimulation.step(0)``, the same
call the node makes before its clock starts, and its message packer ``NodeMessages``, which
loads the impact-row kernel; scenes the node refuses are skipped) and a
one-millisecond offline run (``study simulate``: the energy ledger's kernel forms). Prints one
line per scene with the seconds it took.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('scenes', nargs='*', help='scene names (default: every shipped scene)')
    parser.add_argument('--offline', action='store_true',
                        help="also compile what 'study simulate' calls (the energy ledger)")
    args = parser.parse_args(argv)
    scenes = args.scenes or sorted(p.stem for p in (ROOT / 'config' / 'scenes').glob('*.yaml'))
    start = time.monotonic()
    from impact_damper_sim.cli.study import main as study
    from impact_damper_sim.live.realtime import LiveSimulation
    from impact_damper_sim.live.streams import live_scene
    from impact_damper_sim.recording.node_messages import NodeMessages
    from impact_damper_sim.scene.schema import SceneError
    print(f'compiling the kernels of {len(scenes)} scenes into the cache (once; a later start '
          'loads them)', flush=True)
    failed = 0
    for scene in scenes:
        t0 = time.monotonic()
        try:
            model, target = live_scene(scene)
        except SceneError:
            live = 'offline only'   # the node refuses it (offline_only): no live warm-up
        else:
            simulation = LiveSimulation(model, initial_target=target)
            simulation.step(0)
            NodeMessages(simulation, model)
            live = 'live'
        if args.offline:
            with contextlib.redirect_stdout(io.StringIO()) as out:
                code = study(['simulate', scene, '--duration', '2 ms', '--window', '1 ms'])
            if code:
                failed += 1
                print(f'  {scene}: study simulate failed ({code}): {out.getvalue()[-300:]}',
                      file=sys.stderr)
        print(f'  {scene:<12} {live:<12} {time.monotonic() - t0:5.1f} s', flush=True)
    print(f'kernels ready after {time.monotonic() - start:.0f} s', flush=True)
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
