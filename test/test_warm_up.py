"""The node's warm-up compiles (or loads) every kernel a live run calls (issue 24 item 4).

`VibrationNode` calls ``LiveSimulation.step(0)`` while it reports "loading the scene and the
compiled kernels", before its clock starts. A kernel first typed after that is compiled in a
paced tick: on a cold cache the stream then falls behind real time (the streaming low-pass
``sosfilt`` took 1.4 s of the first tick). Each scene runs in its own interpreter, as the node
does, so a kernel one scene compiled cannot hide what another needs. Counted: the kernel
overloads added (compiled or loaded from the cache; Numba adds both through
``add_overload``) after the warm-up, over 0.6 s of simulated time at the node's defaults, with
a speed command and a noise change in the middle. Expected: none. And the kernels a cold
start compiles in helper processes from its first second (``kernels/prefetch.py``) are called
with exactly the argument types listed there.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCENES = sorted(p.stem for p in (ROOT / 'config' / 'scenes').glob('*.yaml'))

RUN = r'''
import json, sys
from impact_damper_sim.integrate import kernels
from impact_damper_sim.live.realtime import LiveSimulation
from impact_damper_sim.live.streams import live_scene
from impact_damper_sim.scene.schema import SceneError
added = []
original = kernels.Kernel.add_overload
def counting(self, cres):
    added.append(f'{self.py_func.__name__}{tuple(str(a) for a in cres.signature.args)}')
    return original(self, cres)
kernels.Kernel.add_overload = counting
try:
    model, target = live_scene(sys.argv[1])
except SceneError as exc:
    print(json.dumps({'refused': str(exc)}))
    raise SystemExit
live = LiveSimulation(model, initial_target=target)
live.step(0)
warm = len(added)
chunk = max(1, int(live.sample_rate * 0.02))   # the node's 20 ms ticks
failure = None
for t_end, change in ((0.3, True), (0.6, False)):
    while live.t < t_end and failure is None:
        if live.step(chunk) is None:
            failure = live.failure
    if change:
        if live.has_rotor and target is not None:   # a gyroscopic scene keeps its one speed
            live.command_speed(0.5 * target)
        live.set_noise(1e-3, seed=1)
import importlib
from impact_damper_sim.integrate.kernels.prefetch import ENTRIES, parse_types
stale = [name for module, name, spec in ENTRIES if parse_types(spec) not in
         getattr(importlib.import_module(module), name).internal().overloads]
print(json.dumps({'warm_up': added[:warm], 'after': added[warm:], 'failure': failure,
                  'stale_prefetch': stale}))
'''


@pytest.mark.parametrize('scene', SCENES)
def test_no_kernel_is_first_needed_after_the_warm_up(scene):
    proc = subprocess.run([sys.executable, '-c', RUN, scene], cwd=ROOT, capture_output=True,
                          text=True, timeout=600, env=dict(os.environ))
    assert proc.returncode == 0, proc.stderr[-3000:]
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    if 'refused' in result:
        assert 'offline studies only' in result['refused']
        pytest.skip(f'{scene}: the node refuses it ({result["refused"][:80]}...)')
    assert result['failure'] is None, result['failure']
    assert result['warm_up'], 'the warm-up loaded no kernel: nothing was measured'
    # what a cold start has helper processes compile first is what this scene calls
    assert result['stale_prefetch'] == [], 'kernels/prefetch.py ENTRIES: wrong argument types'
    assert result['after'] == [], (
        f'{scene}: kernels typed after the warm-up (compiled in a paced tick on a cold cache)')
