"""Shared pieces of the study tasks: build a point's scene, run it, read values back.

Everything here runs on a worker; it imports NumPy and the simulator.
"""
from __future__ import annotations

import re

import numpy as np

_TOKEN_RE = re.compile(r'[^.\[\]]+')


def load_point(point):
    """Build the scene of a study point.

    Parameters
    ----------
    point : Point
        Its ``scene`` and ``overrides`` are used.

    Returns
    -------
    SceneModel
        The built scene.
    """
    from ..scene.build import load
    return load(point.scene, list(point.overrides))


def start(scene, **options):
    """Return a simulation of ``scene`` with its own ``simulation`` method and dt.

    Parameters
    ----------
    scene : SceneModel
        The scene.
    **options
        Integrator options (``q0``, ``qd0``, ...).

    Returns
    -------
    Simulation
        At rest at t = 0 s unless ``q0``/``qd0`` are given.
    """
    cfg = scene.scene['simulation']
    return scene.make_simulation(cfg['method'], cfg['dt'], **options)


def lookup(scene_dict, path):
    """Return the value at a dotted scene key (``'impactors.0.clearance'``, ``'a[0].b'``).

    Parameters
    ----------
    scene_dict : dict
        A validated scene (SI units).
    path : str
        Dotted key path, list indices as ``.0`` or ``[0]``.

    Returns
    -------
    object
        The value (SI), or None if the path does not exist.
    """
    node = scene_dict
    for token in _TOKEN_RE.findall(path):
        if isinstance(node, list) and token.isdigit() and int(token) < len(node):
            node = node[int(token)]
        elif isinstance(node, dict) and token in node:
            node = node[token]
        else:
            return None
    return node


def window_impact_rates(events, impactor_names, t0, t1):
    """Impacts per second of each impactor in ``(t0, t1]``.

    Parameters
    ----------
    events : ndarray of EVENT_DTYPE
        Events.
    impactor_names : sequence of str
        Names, in impactor order.
    t0, t1 : float
        Window (s).

    Returns
    -------
    dict of str to float
        Impacts per second (1/s).
    """
    from ..integrate.events import EVENT_KINDS
    impact = EVENT_KINDS.index('impact')
    mine = events[(events['kind'] == impact) & (events['t'] > t0) & (events['t'] <= t1)]
    span = max(t1 - t0, 1e-300)
    return {name: int((mine['impactor'] == j).sum()) / span
            for j, name in enumerate(impactor_names)}


def finite_or_none(x):
    """Return ``float(x)``, or None for NaN and infinities (strict JSON)."""
    x = float(x)
    return x if np.isfinite(x) else None


def check_memory(scene, duration=None, dt=None):
    """Refuse up front a study whose runs would not fit in memory.

    Parameters
    ----------
    scene : SceneModel
        The study's base scene.
    duration, dt : float, optional
        Longest run (s) and smallest step (s); default the scene's ``simulation`` values.

    Raises
    ------
    TooLarge
        With the estimate (a ``ValueError``: ``study`` exits 2).
    """
    from ..integrate.memory import TooLarge, check_allocation
    cfg = scene.scene['simulation']
    duration = cfg['duration'] if duration is None else duration
    dt = cfg['dt'] if dt is None else dt
    try:
        check_allocation(round(duration / dt), len(scene.model.sensor_names))
    except TooLarge as exc:
        raise TooLarge(exc.n_steps, exc.n_bytes, exc.limit,
                       context=f'each run: dt = {dt:g} s over {duration:g} s',
                       advice='raise simulation.dt (--dt) or shorten simulation.duration '
                              '(--duration)') from None
