"""The same inputs give the same bits: within a process and across processes.

A stability study promises that rerunning it gives the same verdict, and ``study record``
the same messages byte for byte. The Jeffcott-like cantilever of ``test_studies`` (isotropic,
so its two modes are degenerate, and ``solver: sparse``) used to give another modal basis on
every build: ``eigsh`` drew its Lanczos start vector from OS entropy, and a degenerate pair
came back rotated by a random angle (up to about 0.01 rad), which moved the initial
perturbation and let an impacting run end stable or unstable (growth ratio 0.48-0.59 over 60
repetitions in one process, impact counts differing; the linear run in its last digits).
"""
import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from impact_damper_sim.modal.basis import _canonical_basis, modal_reduction
from impact_damper_sim.scene.build import load
from impact_damper_sim.studies.measure import start

HERE = Path(__file__).resolve().parent
KCC_KEY = 'structure.cross_couplings.0.kcc'
# test_studies.JEFFCOTT (kept here so the child process needs only this file), 1 s
JEFFCOTT = ['structure.sections.analog.Iy=12 in^4', 'modal.n_modes=2',
            'structure.cross_couplings=[{node: 5, kcc: 2400 N/m}]', 'forcing=[]',
            'sensors=[{name: y, node: 5, dof: uy}, {name: z, node: 5, dof: uz}]',
            'simulation.duration=1 s']
CASES = {'linear': JEFFCOTT + ['impactors=[]'],
         'impacting': JEFFCOTT + ['impactors.0.mass_ratio=0.04',
                                  'impactors.0.clearance=0.2 mil']}


def fingerprints():
    """Digest of every stage of each case: basis, modal model, run (samples and events)."""
    out = {}
    for name, overrides in CASES.items():
        scene = load('cantilever', overrides)
        q0 = np.random.default_rng(7).standard_normal(scene.model.n) * 1e-4
        sim = start(scene, q0=q0)
        samples = sim.advance_to(scene.scene['simulation']['duration'])
        events = sim.take_events()
        stages = {'basis': [scene.basis.omega, scene.basis.shapes],
                  'model': [scene.model.K, scene.model.C, scene.model.sensors],
                  'run': [samples.t, samples.displacement, events]}
        out[name] = {stage: hashlib.sha256(b''.join(np.ascontiguousarray(a).tobytes()
                                                    for a in arrays)).hexdigest()[:16]
                     for stage, arrays in stages.items()}
        out[name]['impacts'] = int(events.size)
    return out


def test_same_bits_in_one_process_and_in_another():
    first = fingerprints()
    assert first['impacting']['impacts'] > 0 and first['linear']['impacts'] == 0
    assert fingerprints() == first
    code = (f'import json, sys; sys.path.insert(0, {str(HERE)!r}); '
            'import test_determinism as t; print(json.dumps(t.fingerprints()))')
    child = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                           env=dict(os.environ, PYTHONHASHSEED='12345'), check=True)
    assert json.loads(child.stdout.strip().splitlines()[-1]) == first


def test_a_degenerate_pair_gets_the_same_basis_from_any_solver():
    """The isotropic cantilever's y and z modes come out pure y and pure z, whatever rotation
    of them the solver returned: dense and sparse agree to the dense solver's accuracy."""
    scene = load('cantilever', CASES['linear'])
    system = scene.system
    uy, uz = system.index(5, 'uy'), system.index(5, 'uz')
    bases = {m: modal_reduction(system, n_modes=2, method=m) for m in ('sparse', 'dense')}
    for basis in bases.values():
        tip = basis.rows([uy, uz])
        assert tip[0, 0] > 0 and tip[1, 1] > 0
        assert abs(tip[1, 0]) < 1e-12 * tip[0, 0] and abs(tip[0, 1]) < 1e-9 * tip[1, 1]
    assert bases['sparse'].shapes == pytest.approx(bases['dense'].shapes, abs=1e-6)


def test_canonical_basis_depends_on_the_span_only():
    rng = np.random.default_rng(1)
    phi = np.linalg.qr(rng.standard_normal((12, 5)))[0]
    lam = np.array([1.0, 4.0, 4.0, 4.0, 9.0])
    c, s = np.cos(0.7), np.sin(0.7)
    rot = np.eye(5)
    rot[1:4, 1:4] = np.linalg.qr(rng.standard_normal((3, 3)))[0] @ [[c, -s, 0], [s, c, 0],
                                                                   [0, 0, 1]]
    a, b = _canonical_basis(lam, phi), _canonical_basis(lam, phi @ rot)
    assert np.array_equal(a[:, [0, 4]], phi[:, [0, 4]])      # single modes untouched
    assert b == pytest.approx(a, abs=1e-14)
    assert a.T @ a == pytest.approx(np.eye(5), abs=1e-14)    # still orthonormal
