"""Rotordynamics of a scene: whirl modes at its speed, and the Campbell diagram over speed.

The eigen-analysis is :mod:`impact_damper_sim.modal.whirl` (one speed) and
:mod:`impact_damper_sim.modal.tracking` (over speed); this module turns a built scene
into its rotating model and the results into JSON-ready data (``study modes``, ``study
campbell``). The plots are in :mod:`.campbell_plot`.

**The model.** The scene's modal model, the one the simulation integrates: the retained
modes of the symmetric stiffness (``modal.n_modes``, ``modal.f_max``), the modal stiffness
with the cross-coupled terms ``Phi^T K_skew Phi``, the modal damping (tare and physical
dampers), and the gyroscopic coupling ``Omega Phi^T G Phi`` of the ``rotor.gyroscopic`` nodes
(their point-mass polar inertia spinning about +X). At the scene's speed this is exactly the
simulated model's ``C`` (``test/test_whirl.py`` checks it). A Campbell diagram varies only the
speed of the gyroscopic coupling; the cross-coupled stiffness and the damping do not depend on
the speed in the scene format. The modal subspace keeps 100 speeds to about 0.1 s (a state
matrix of twice the retained modes per speed instead of twice every DOF with mass). What it
costs against every DOF (``condensed_rotor``, ``test/test_whirl.py``): on ``ross_rotor``'s 16
modes at most 8e-5 on the 8 lowest whirl frequencies up to 10,000 rpm, directions the same
(retain more modes with ``--set modal.n_modes=N`` where the coupling needs them).
"""
from __future__ import annotations

import time

import numpy as np

#: rad/s per rpm.
RPM = np.pi / 30.0


def rotor_model(scene):
    """The scene's rotating model in its modal coordinates, gyroscopic matrix per unit speed.

    Parameters
    ----------
    scene : SceneModel
        A built scene.

    Returns
    -------
    RotorModel
        ``M = I``, ``C`` the modal damping (1/s), ``K`` the modal stiffness (1/s^2), ``G`` the
        modal gyroscopic matrix per unit speed (dimensionless); a scene without ``rotor`` has
        no spin axis.
    """
    from ..modal.whirl import gyroscopic_matrix, modal_rotor
    polar = scene.polar_inertia()
    G = gyroscopic_matrix(scene.system, polar) if polar else None
    return modal_rotor(scene.basis, G, spin_axis=scene.scene['rotor'] is not None)


def scene_speed(scene):
    """The scene's constant rotor speed (rad/s), or None (no rotor, or a varying speed)."""
    from ..scene.excitation import ConstantSpeed
    profile = scene.speed_profile
    return float(profile.omega) if isinstance(profile, ConstantSpeed) else None


def _diagonal(a):
    from ..modal.basis import DIAGONAL_RTOL  # scipy: not when the command line starts
    scale = np.abs(a).max(initial=0.0)
    return bool(np.abs(a - np.diag(np.diag(a))).max(initial=0.0) <= DIAGONAL_RTOL * scale)


def node_positions(scene):
    """Coordinates of the scene's nodes, from its ``structure`` (as the loader numbers them).

    Parameters
    ----------
    scene : dict
        A validated scene (SI units).

    Returns
    -------
    dict of int to ndarray
        Node id to its global coordinates (m).
    """
    st = scene['structure']
    if st['kind'] == 'sdof':
        return {0: np.zeros(3)}
    nodes = {int(n['id']): np.asarray(n['xyz'], dtype=float) for n in st['nodes'] or ()}
    for line in st['lines'] or ():
        p0, p1 = np.asarray(line['from'], dtype=float), np.asarray(line['to'], dtype=float)
        n = line['n_elements']
        first = line['first_node']
        if first is None:
            first = max(nodes) + 1 if nodes else 0
        for k in range(n + 1):
            nodes.setdefault(first + k, p1 if k == n else p0 + (p1 - p0) * (k / n))
    return nodes


def whirl_at_speed(scene):
    """The damped whirl modes of the simulated model at the scene's speed.

    Parameters
    ----------
    scene : SceneModel
        A built scene.

    Returns
    -------
    modes : WhirlModes
        Of ``scene.model`` (its ``K`` and ``C``, gyroscopic coupling at the scene's speed
        included).
    stations : OrbitStations
        The orbit stations of the modal coordinates.
    """
    from ..modal.whirl import RotorModel, orbit_stations, whirl_modes
    model = scene.model
    speed = scene_speed(scene) or 0.0
    rotor = RotorModel(M=np.asarray(model.M, dtype=float), C=np.asarray(model.C, dtype=float),
                       K=np.asarray(model.K, dtype=float), G=np.zeros_like(model.K),
                       stations=orbit_stations(scene.system, scene.basis.rows),
                       spin_axis=scene.scene['rotor'] is not None)
    return whirl_modes(rotor, speed), rotor.stations


def describe_whirl(scene):
    """What ``study modes`` adds to the modal-basis listing: the damped whirl modes.

    Parameters
    ----------
    scene : SceneModel
        A built scene.

    Returns
    -------
    dict
        ``spin_axis`` (the scene has a rotor; without one every direction is ``none``),
        ``rotor_speed_rad_s`` and ``rotor_speed_rpm`` (None without a constant speed: then
        the model has no speed-dependent term), ``coupled`` (the simulated modal ``K`` or ``C``
        is not diagonal: cross-coupled stiffness, physical dampers or gyroscopic coupling),
        ``whirl``: one entry per damped mode by frequency, ``mode`` (from 1),
        ``frequency_hz`` (damped natural frequency), ``direction`` (``forward``,
        ``backward``, ``none``), ``log_dec`` (``-2 pi Re/Im``), ``damping_ratio``
        (``-Re/|lambda|``), ``growth_rate_1_s`` (``Re(lambda)``) and ``whirl_index``
        (-1 backward circular .. +1 forward circular), and ``n_overdamped`` (real
        eigenvalues left out).
    """
    modes, _ = whirl_at_speed(scene)
    speed = scene_speed(scene)
    model = scene.model
    entries = [{'mode': j + 1, 'frequency_hz': float(modes.frequency_hz[j]),
                'direction': modes.directions[j], 'log_dec': float(modes.log_dec[j]),
                'damping_ratio': float(modes.damping_ratio[j]),
                'growth_rate_1_s': float(modes.eigenvalues[j].real),
                'whirl_index': float(modes.whirl_index[j])}
               for j in range(modes.eigenvalues.size)]
    return {'spin_axis': scene.scene['rotor'] is not None, 'rotor_speed_rad_s': speed,
            'rotor_speed_rpm': None if speed is None else speed / RPM,
            'coupled': not (_diagonal(np.asarray(model.K)) and _diagonal(np.asarray(model.C))),
            'whirl': entries, 'n_overdamped': modes.n_overdamped}


def whirl_shapes(scene, mode_numbers=None):
    """Orbit shapes along the shaft of whirl modes at the scene's speed, for a plot.

    Parameters
    ----------
    scene : SceneModel
        A built scene.
    mode_numbers : sequence of int, optional
        Whirl modes (numbered from 1, as :func:`describe_whirl`); default the first six.

    Returns
    -------
    dict
        ``axial_m`` (x of each translation station, m, ascending), ``nodes``, and ``modes``:
        per mode ``mode``, ``frequency_hz``, ``direction``, ``log_dec``, ``major`` (major
        semi-axis per station, scaled to a largest value of 1) and ``signed_minor`` (minor
        semi-axis, same scale, > 0 where the orbit turns with the spin, < 0 against it).

    Raises
    ------
    ValueError
        A mode number out of range, or a scene without two lateral translations at a node.
    """
    from ..modal.whirl import orbit_radii
    modes, stations = whirl_at_speed(scene)
    m = modes.eigenvalues.size
    numbers = list(mode_numbers) if mode_numbers else list(range(1, min(m, 6) + 1))
    bad = [k for k in numbers if not 1 <= k <= m]
    if bad:
        raise ValueError(f"mode(s) {', '.join(map(str, bad))} out of range 1..{m} (the "
                         'damped whirl modes of study modes)')
    trans = stations.select('translation')
    if trans.nodes.size == 0:
        raise ValueError('no node moves in both uy and uz: no orbit to draw')
    xyz = node_positions(scene.scene)
    axial = np.array([xyz[int(n)][0] for n in trans.nodes])
    order = np.argsort(axial, kind='stable')
    spin = -1.0 if (scene_speed(scene) or 0.0) < 0 else 1.0
    out = []
    for k in numbers:
        a_f, a_b = orbit_radii(trans, modes.shapes[:, k - 1])
        major = (a_f + a_b)[order]
        scale = major.max() or 1.0
        out.append({'mode': k, 'frequency_hz': float(modes.frequency_hz[k - 1]),
                    'direction': modes.directions[k - 1],
                    'log_dec': float(modes.log_dec[k - 1]),
                    'major': (major / scale).tolist(),
                    'signed_minor': (spin * (a_f - a_b)[order] / scale).tolist()})
    return {'scene': scene.name, 'axial_m': axial[order].tolist(),
            'nodes': trans.nodes[order].tolist(), 'rotor_speed_rpm':
            None if scene_speed(scene) is None else scene_speed(scene) / RPM, 'modes': out}


def campbell_study(scene, speeds_rpm, harmonics=(1.0,), overrides=()):
    """The Campbell diagram of a scene: whirl modes tracked over speed, criticals, onset.

    Parameters
    ----------
    scene : str
        Scene name or path.
    speeds_rpm : sequence of float
        Spin speeds (rpm), >= 0, strictly increasing, at least two.
    harmonics : sequence of float
        Orders of the excitation lines (``1`` = 1X, the unbalance), > 0.
    overrides : sequence of str
        ``key=value`` scene overrides.

    Returns
    -------
    dict
        ``scene``, ``source``, ``overrides``, ``model`` (coordinates, retained modes and why,
        gyroscopic nodes, cross-couplings), ``speeds_rpm``, ``harmonics``, ``branches`` (per
        branch, numbered from 1 by frequency at the first speed: ``frequency_hz``,
        ``log_dec``, ``damping_ratio``, ``direction`` per speed), ``critical_speeds`` (per
        crossing of a branch with a harmonic line: ``harmonic``, ``branch``, ``speed_rpm``,
        ``frequency_hz``, ``direction``, ``log_dec``), ``onset`` (the first speed where a log
        decrement turns negative: ``speed_rpm``, ``from_start``, ``branch``,
        ``frequency_hz``, ``direction``; None if stable over the range), ``rows`` (one per
        speed and branch, for CSV) and ``wall_time_s`` (the eigen-analysis, tracking,
        critical speeds and onset, s).

    Raises
    ------
    ValueError
        Bad speeds or harmonics, or a scene without ``rotor`` (nothing spins); a
        ``SceneError`` (a ValueError) for a bad scene.
    """
    from ..modal.tracking import campbell, critical_speeds, instability_onset
    from ..scene.build import load
    speeds_rpm = [float(s) for s in speeds_rpm]
    harmonics = [float(h) for h in harmonics]
    problems = []
    if len(speeds_rpm) < 2:
        problems.append('--speeds: a Campbell diagram needs at least two speeds')
    if any(not (np.isfinite(s) and s >= 0) for s in speeds_rpm):
        problems.append('--speeds: speeds must be finite and >= 0 rpm')
    elif np.any(np.diff(speeds_rpm) <= 0):
        problems.append('--speeds: speeds must be strictly increasing')
    if not harmonics or any(not (np.isfinite(h) and h > 0) for h in harmonics):
        problems.append('--harmonics: orders must be finite and > 0')
    if problems:
        raise ValueError('; '.join(problems))
    built = load(scene, overrides)
    if built.scene['rotor'] is None:
        raise ValueError("a Campbell diagram needs a rotor (scene key 'rotor'): nothing spins "
                         f'in scene {built.name!r}')
    rotor = rotor_model(built)
    import importlib
    importlib.import_module('scipy.optimize')   # its import (0.3 s and more) is not the analysis
    start = time.perf_counter()
    data = campbell(rotor, np.asarray(speeds_rpm) * RPM)
    crit = critical_speeds(data, harmonics)
    onset = instability_onset(data)
    wall = time.perf_counter() - start
    freq, log_dec, zeta = data.frequency_hz, data.log_dec, data.damping_ratio

    def num(x):
        return float(x) if np.isfinite(x) else None

    branches = [{'branch': b + 1,
                 'frequency_hz': [num(v) for v in freq[:, b]],
                 'log_dec': [num(v) for v in log_dec[:, b]],
                 'damping_ratio': [num(v) for v in zeta[:, b]],
                 'direction': [d or None for d in data.directions[:, b]]}
                for b in range(data.n_branches)]
    rows = [{'speed_rpm': s, 'branch': b + 1, 'frequency_hz': num(freq[k, b]),
             'log_dec': num(log_dec[k, b]), 'damping_ratio': num(zeta[k, b]),
             'direction': data.directions[k, b] or None,
             'whirl_index': num(data.whirl_index[k, b])}
            for k, s in enumerate(speeds_rpm) for b in range(data.n_branches)]
    gyro = sorted(built.polar_inertia())
    couplings = built.scene['structure'].get('cross_couplings') or []
    return {
        'study': 'campbell', 'scene': built.name, 'source': built.source,
        'overrides': list(built.overrides),
        'model': {'coordinates': f'{built.basis.n_modes} retained modes of the scene '
                                 '(the simulated modal model)',
                  'n_modes': int(built.basis.n_modes),
                  'selection_reason': built.basis.selection_reason,
                  'gyroscopic_nodes': gyro,
                  'cross_couplings': [{'node': c['node'], 'kcc_N_m': c['kcc'],
                                       'dofs': list(c['dofs'])} for c in couplings]},
        'speeds_rpm': speeds_rpm, 'harmonics': harmonics, 'branches': branches,
        'critical_speeds': [{'harmonic': c.harmonic, 'branch': c.branch + 1,
                             'speed_rpm': c.speed / RPM, 'frequency_hz': c.frequency_hz,
                             'direction': c.direction, 'log_dec': c.log_dec} for c in crit],
        'onset': None if onset is None else {
            'speed_rpm': onset.speed / RPM, 'from_start': onset.from_start,
            'branch': None if onset.branch is None else onset.branch + 1,
            'frequency_hz': onset.frequency_hz, 'direction': onset.direction},
        'rows': rows, 'wall_time_s': wall}


__all__ = ['RPM', 'campbell_study', 'describe_whirl', 'node_positions',
           'rotor_model', 'scene_speed', 'whirl_at_speed', 'whirl_shapes']
