"""What a scene streams live: the scene with a commanded rotor, its accelerometers, its rates.

* :func:`live_scene` loads a scene for live stepping, its rotor commanded;
* :func:`accelerometers` makes one triaxial :class:`Accelerometer` per instrumented node;
* :func:`default_sample_rate` and :func:`default_imu_rate` give the output rate the scene's
  sensors imply and the rate of the decimated per-sample stream.

These decide what :class:`~impact_damper_sim.live.realtime.LiveSimulation` streams before
it steps; they are kept apart from the stepping (:mod:`.realtime`) because they read only
the scene, and the tests and benches call them on their own. Everything is SI.

The rotor of a live scene is always *commanded*: a scene whose speed profile is a ramp,
constant or piecewise is converted to a commanded profile that starts at the profile's
initial speed and is commanded at once to its final speed, under the rate limit (the paper's
ramp becomes the same linear ramp at ``final_speed / ramp_time``).
"""
from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

import numpy as np

from ..scene.schema import SceneError

if TYPE_CHECKING:
    from ..scene.build import SceneModel

#: Default anti-alias cutoff of a sensor without a scene ``lowpass``, times the output rate
#: (0.4 keeps a 4th-order Butterworth ~ -30 dB at the output Nyquist frequency).
DEFAULT_LOWPASS_FRACTION = 0.4


#: Output rate of a scene whose sensors state no ``lowpass`` (Hz).
FALLBACK_SAMPLE_RATE = 2000.0
#: Output rate over the highest anti-alias cutoff that :func:`default_sample_rate` keeps at
#: least (dimensionless): the cutoff sits below the output Nyquist frequency with margin
#: (vibration analysers use 2.56).
SAMPLE_RATE_OVER_CUTOFF = 2.5


def default_sample_rate(scene_model: SceneModel) -> float:
    """The output sample rate a scene implies (Hz), used when none is requested.

    The lowest submultiple of the scene's integrator rate ``1/simulation.dt`` that is at least
    :data:`SAMPLE_RATE_OVER_CUTOFF` x the highest ``lowpass`` of the scene's sensors, so the
    integrator keeps the scene's step; :data:`FALLBACK_SAMPLE_RATE` when no sensor states a
    low-pass. HPOTP (800 Hz low-pass, 0.1 ms): 2000 Hz; RBS (5 kHz, 50 us): 20 kHz.

    Parameters
    ----------
    scene_model : SceneModel
        Built scene.

    Returns
    -------
    float
        Sample rate (Hz).
    """
    cutoffs = [s['lowpass'] for s in scene_model.scene['sensors'] if s['lowpass'] is not None]
    if not cutoffs:
        return FALLBACK_SAMPLE_RATE
    need = SAMPLE_RATE_OVER_CUTOFF * max(cutoffs)
    f_step = 1.0 / float(scene_model.scene['simulation']['dt'])
    if f_step < need * (1 - 1e-12):
        return need   # the integrator step shrinks to a submultiple of the output period
    k = max(1, math.floor(f_step / need * (1 + 1e-12)))
    return f_step / k


#: Highest default rate of the live per-sample ``Imu`` stream (Hz). The full-rate signal goes
#: in batches; the per-sample stream is for clients that take one message at a time. A stock
#: Python subscriber received a median 53 % of a 2 kHz stream and 90 % of a 1 kHz one with
#: the other core busy, 76 % and 98 % with it idle, on this shared machine
#: (bench/stream_formats.py); batches 100 %.
LIVE_IMU_MAX_RATE = 1000.0


def default_imu_rate(sample_rate: float, limit: float = LIVE_IMU_MAX_RATE) -> float:
    """The live per-sample rate for an output rate: the highest ``sample_rate / k`` (k a
    whole number) not above ``limit`` (Hz)."""
    return sample_rate / max(1, math.ceil(sample_rate / limit - 1e-9))



@dataclasses.dataclass(frozen=True)
class Accelerometer:
    """A triaxial accelerometer (with rate gyro) at a node of the structure.

    Attributes
    ----------
    name : str
        Topic suffix (``accel/<name>``).
    frame_id : str
        Sensor frame (axes parallel to the global frame).
    node : int
        Finite-element node (dimensionless).
    lowpass_hz : float
        Anti-alias cutoff (Hz).
    """

    name: str
    frame_id: str
    node: int
    lowpass_hz: float


def live_scene(scene: str | os.PathLike[str], overrides: Iterable[str] = (), *,
               speed_rate_limit: float | None = None) -> tuple[SceneModel, float | None]:
    """Load a scene for live stepping, with its rotor speed made commanded.

    Parameters
    ----------
    scene : str or os.PathLike
        Scene name or file.
    overrides : sequence of str
        ``key=value`` scene overrides.
    speed_rate_limit : float, optional
        Rate limit of speed commands (rad/s^2). Default: the scene's ``max_rate`` for a
        commanded speed, ``final_speed / ramp_time`` for the paper's ramp, the steepest
        segment for a piecewise profile, 100 rad/s^2 otherwise.

    Returns
    -------
    scene_model : SceneModel
        Built scene (rotor speed kind ``commanded``).
    initial_target : float or None
        Speed to command at start (rad/s): the original profile's final speed; None
        without a rotor.

    Raises
    ------
    SceneError
        Any scene problem, naming the key; a scene whose ``offline_only`` says why it
        cannot run live.
    """
    from ..integrate.kernels.prefetch import prefetch
    from ..scene.build import build
    from ..scene.catalog import validated
    from ..scene.excitation import CommandedSpeed, speed_profile

    prefetch()   # a live run follows: a cold cache starts compiling the event search now
    overrides = tuple(overrides)
    spec: dict[str, Any]
    spec, path = validated(scene, overrides)
    if spec['offline_only']:
        raise SceneError(f"scene {spec['name']!r} is for offline studies only: "
                         f"{spec['offline_only']}", str(path))
    rotor = spec['rotor']
    if rotor is None:
        return build(spec, source=str(path), overrides=overrides), None
    profile = speed_profile(rotor['speed'])
    final = profile.final_speed
    rate = (profile.max_rate if isinstance(profile, CommandedSpeed)
            else profile.steepest_rate or 100.0) \
        if speed_rate_limit is None else speed_rate_limit
    if not (math.isfinite(rate) and rate > 0):
        raise SceneError(f'speed rate limit: must be a finite rate > 0 rad/s^2, got {rate}')
    if rotor['gyroscopic'] is not None:   # one constant speed (LiveSimulation.command_speed)
        return build(spec, source=str(path), overrides=overrides), None
    # the same scene with the rotor commanded: a new mapping, as validating the override
    # would give (without reading and validating the file twice), built once
    initial = float(profile.speed(np.asarray(0.0)))
    commanded = dict(rotor['speed'], kind='commanded', speed=initial, max_rate=float(rate),
                     final_speed=None, ramp_time=None, times=None, speeds=None)
    spec = dict(spec, rotor=dict(rotor, speed=commanded))
    overrides += (f'rotor.speed={{kind: commanded, speed: {initial!r}, '
                  f'max_rate: {float(rate)!r}}}',)
    return build(spec, source=str(path), overrides=overrides), final


def accelerometers(scene_model: SceneModel, sample_rate: float) -> list[Accelerometer]:
    """The accelerometers of a scene: one per instrumented node.

    An accelerometer reads all three axes of its node, so scene sensors at one node (several
    DOFs of it) are one accelerometer and one stream, never two streams of the same data. It
    is named by the sensors' shared ``frame_id``, or ``<scene>_<sensor>`` for a single
    sensor without one, or ``<scene>_node<N>`` for several sensors without one.

    Parameters
    ----------
    scene_model : SceneModel
        Built scene.
    sample_rate : float
        Output sample rate (Hz); sets the default anti-alias cutoff.

    Returns
    -------
    list of Accelerometer

    Raises
    ------
    SceneError
        One ``frame_id`` at two nodes, or two ``frame_id`` at one node.
    """
    by_node: dict[int, list[dict[str, Any]]] = {}
    for s in scene_model.scene['sensors']:
        by_node.setdefault(s['node'], []).append(s)
    out: list[Accelerometer] = []
    frames: dict[str, int] = {}

    for node, sensors in by_node.items():
        named = sorted({s['frame_id'] for s in sensors if s['frame_id']})
        if len(named) > 1:
            raise SceneError(f"scene key 'sensors': node {node} has sensors with frame_id "
                             f"{' and '.join(map(repr, named))}; one node is one triaxial "
                             'accelerometer: give its sensors one frame_id',
                             scene_model.source)
        if named:
            frame = named[0]
        elif len(sensors) == 1:
            frame = f"{scene_model.name}_{sensors[0]['name']}"
        else:
            frame = f'{scene_model.name}_node{node}'
        if frame in frames:
            raise SceneError(f"scene key 'sensors': frame_id {frame!r} is used at nodes "
                             f'{frames[frame]} and {node}; one frame is one node',
                             scene_model.source)
        frames[frame] = node
        cutoffs = [s['lowpass'] if s['lowpass'] is not None
                   else DEFAULT_LOWPASS_FRACTION * sample_rate for s in sensors]
        out.append(Accelerometer(frame, frame, node, float(min(cutoffs))))
    return out


__all__ = ['Accelerometer', 'DEFAULT_LOWPASS_FRACTION', 'FALLBACK_SAMPLE_RATE',
           'LIVE_IMU_MAX_RATE', 'SAMPLE_RATE_OVER_CUTOFF', 'accelerometers',
           'default_imu_rate', 'default_sample_rate', 'live_scene']
