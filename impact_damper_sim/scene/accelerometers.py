"""Each accelerometer's channel in a scene: the sensors at one node are one accelerometer.

Its channel is the one its sensors state, else the scene's ``channel`` (:func:`channel_of`,
one code path for the node, ``study record`` and ``study simulate``). Checked at load
(:func:`accelerometer_problems`): the sensors of one node stating two channels, and a mounted
resonance not above the anti-alias band edge (:func:`resonance_problem`, also asked at run
time for a sensor whose cutoff is set then). The keys and presets are :mod:`.channel_spec`.
"""
from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from typing import Any, Protocol

from .channel_spec import _STAGE_FIELDS
from .schema import Quantity
from .units import SI_UNIT


class BuiltScene(Protocol):
    """What these functions read of a built scene (a :class:`~.build.SceneModel`): its
    validated scene (SI)."""

    scene: dict[str, Any]


__all__ = ['accelerometer_channels', 'accelerometer_problems', 'channel_of',
           'resonance_problem']


def _scene(scene_model: BuiltScene | dict[str, Any]) -> dict[str, Any]:
    return dict(scene_model) if isinstance(scene_model, Mapping) else scene_model.scene


def _by_node(scene: dict[str, Any]) -> dict[int, list[tuple[int, dict]]]:
    nodes: dict[int, list[tuple[int, dict]]] = {}
    for i, s in enumerate(scene['sensors']):
        nodes.setdefault(s['node'], []).append((i, s))
    return nodes


def _same(a: object, b: object) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return math.isclose(a, b, rel_tol=1e-12, abs_tol=0.0)
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and a == b


def _text(value: object) -> str:
    if value is None:
        return 'off'
    if isinstance(value, float):
        return f'{value:.6g}'
    if isinstance(value, list):
        return '[' + ', '.join(_text(v) for v in value) + ']'
    if isinstance(value, dict):
        return '{' + ', '.join(f'{k}: {_text(v)}' for k, v in value.items()) + '}'
    return str(value)


def _label(channel: dict[str, Any], differing: str) -> str:
    text = f"preset {channel['preset']}"
    if differing == 'preset':
        return text
    value, field = channel[differing], _STAGE_FIELDS[differing]
    unit = (f' {SI_UNIT[field.dimension]}' if isinstance(field, Quantity) and value is not None
            else '')
    return f'{text}, {differing} {_text(value)}{unit}'


def resonance_problem(channel: dict[str, Any], band_edge: float, source: str = '') -> str | None:
    """The refusal of a mounted resonance not above the anti-alias band edge, or None.

    Parameters
    ----------
    channel : dict
        A resolved channel.
    band_edge : float
        The accelerometer's anti-alias low-pass cutoff (Hz).
    source : str, optional
        Where the cutoff comes from, shown after it (``'sensors[0].lowpass'``).

    Returns
    -------
    str or None
        The message (without the key), naming both frequencies; None when the resonance is
        off or above the band edge.
    """
    resonance = channel['resonance']
    if resonance is None or resonance['frequency'] > band_edge:
        return None
    origin = '' if channel['preset'] == 'ideal' else f" (preset {channel['preset']})"
    source = f' ({source})' if source else ''
    return (f"{resonance['frequency']:.6g} Hz{origin} is not above the anti-alias band edge "
            f'{band_edge:.6g} Hz{source}; a mounted resonance must lie above the measured '
            'band: raise it, or lower the lowpass')


def accelerometer_problems(scene: BuiltScene | dict[str, Any]) -> list[tuple[str, str]]:
    """Check every accelerometer's channel against its sensors (run at load).

    Parameters
    ----------
    scene : dict or SceneModel
        A validated scene (or a built one).

    Returns
    -------
    list of (str, str)
        ``(key, message)`` pairs: sensors of one node stating two channels (key
        ``sensors``), and a resonance not above the smallest ``lowpass`` the node's sensors
        state (key ``...channel.resonance.frequency`` where the channel was stated).
    """
    scene = _scene(scene)
    problems = []
    for node, sensors in _by_node(scene).items():
        stated = [(i, s) for i, s in sensors if s['channel'] is not None]
        first = stated[0] if stated else None
        conflict = False
        for i, s in stated[1:]:
            a, b = stated[0][1]['channel'], s['channel']
            if not _same(a, b):
                key = next(k for k in a if not _same(a[k], b[k]))
                problems.append(('sensors', f"node {node} has sensors with different channels: "
                                 f"sensors[{stated[0][0]}].channel ({_label(a, key)}) and "
                                 f'sensors[{i}].channel ({_label(b, key)}); one node is one '
                                 'triaxial accelerometer: give its sensors one channel'))
                conflict = True
                break
        if conflict:
            continue
        channel = first[1]['channel'] if first else scene['channel']
        where = f'sensors[{first[0]}].channel' if first else 'channel'
        cutoffs = [(s['lowpass'], i) for i, s in sensors if s['lowpass'] is not None]
        if cutoffs:
            edge, i = min(cutoffs)
            message = resonance_problem(channel, edge, f'sensors[{i}].lowpass, node {node}')
            if message:
                problems.append((f'{where}.resonance.frequency', message))
    return problems


def channel_of(scene_model: BuiltScene | dict[str, Any], node: int) -> dict[str, Any]:
    """The resolved channel of the accelerometer at a node.

    Parameters
    ----------
    scene_model : SceneModel or dict
        A built scene (or its validated ``scene`` dict).
    node : int
        Finite-element node of the accelerometer (dimensionless).

    Returns
    -------
    dict
        A fresh resolved channel (module notes): the channel the node's sensors state, else
        the scene's ``channel``.

    Raises
    ------
    ValueError
        When no sensor sits at ``node`` (naming the nodes that have one), or when its sensors
        state two channels.
    """
    scene = _scene(scene_model)
    nodes = _by_node(scene)
    if node not in nodes:
        raise ValueError(f'no accelerometer at node {node}; accelerometers are at nodes '
                         f'{sorted(nodes) or "none"}')
    for key, message in accelerometer_problems(scene):
        if key == 'sensors' and message.startswith(f'node {node} '):
            raise ValueError(f"scene key 'sensors': {message}")
    stated = [s['channel'] for _, s in nodes[node] if s['channel'] is not None]
    return copy.deepcopy(stated[0] if stated else scene['channel'])


def accelerometer_channels(scene_model: BuiltScene | dict[str, Any]) -> dict[int, dict[str, Any]]:
    """The resolved channel of every accelerometer, by node in sensor order.

    Parameters
    ----------
    scene_model : SceneModel or dict
        A built scene (or its validated ``scene`` dict).

    Returns
    -------
    dict of int to dict
        Node -> resolved channel (see :func:`channel_of`).
    """
    scene = _scene(scene_model)
    return {node: channel_of(scene, node) for node in _by_node(scene)}
