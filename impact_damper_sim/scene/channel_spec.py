"""The accelerometer channel of a scene: its keys, the named presets and their resolution.

A real accelerometer channel is a sensor (mounting, sensitivity, mounted resonance, IEPE
high-pass, noise, bias, measuring range) and a DAQ (anti-alias filter, ADC). The scene states
it per accelerometer location; :class:`~impact_damper_sim.live.channel.SensorChannel` applies
it. This module is the scene side only: the keys, their units and ranges, the presets, and
the SI form the loader hands over.

Keys
----
``channel`` (top level)
    The channel of every accelerometer of the scene; default ``ideal``.
``sensors[].channel``
    The channel of the accelerometer at that sensor's node. Sensors at one node are one
    triaxial accelerometer: those of them that state a channel must state the same one (a
    scene that does not is refused at load, naming both); one stated channel applies to the
    whole accelerometer. None (absent or null) = the top-level ``channel``.

A channel is a preset name (``channel: iepe_100mv_50g``) or a mapping: ``preset`` (default
``ideal``) plus any stage key, which overrides that stage of the preset key by key (the keys
of the stage it does not give keep the preset's values, so ``--set
channel.resonance.frequency=40 kHz`` keeps the preset's ``q``; a ``highpass`` given replaces
the preset's whole, being one of ``corner`` or ``time_constant``), or is ``null`` to switch
the preset's stage off (a key inside a stage set to ``null`` switches that part off)::

    channel:
      preset: iepe_100mv_50g
      sensitivity: 98.7 mV/g          # this sensor's calibration certificate
      transverse: null                # no transverse sensitivity
      orientation: [0 deg, 0 deg, 5 deg]

Stages, each off when absent from the preset and the mapping (the order the chain applies
them in is :mod:`impact_damper_sim.live.channel`'s; ADC noise comes after the anti-alias
filter, the sensor's noise before it):

* ``sensitivity``: nominal acceleration to volts, the value the DAQ divides by.
* ``sensitivity_error`` [x, y, z]: the true sensitivity of axis i is (1 + e_i) x the nominal
  one: the published axis i is scaled by (1 + e_i).
* ``orientation`` [roll, pitch, yaw]: the sensor's axes are the model's axes rotated by
  R = Rz(yaw) Ry(pitch) Rx(roll) (fixed axes X, Y, Z, REP-103); the sensor reads R^T a.
* ``transverse`` {fraction, angle}: sensor axis i also reads ``fraction`` of the acceleration
  perpendicular to it, along the direction at ``angle`` from axis j towards axis k, (i, j, k)
  cyclic: a_i += fraction (cos(angle) a_j + sin(angle) a_k).
* ``resonance`` {frequency, q}: the mounted resonance, a second-order low-pass of natural
  frequency fn and quality factor Q (unit gain at DC), for its in-band rise and phase.
* ``highpass`` {corner}: the IEPE discharge time constant and AC coupling, first order,
  -3 dB at ``corner`` (given as ``time_constant`` tau: corner = 1/(2 pi tau)).
* ``noise_density``: white sensor noise per axis, a one-sided amplitude spectral density as
  datasheets give it (the noise's one-sided PSD is density^2).
* ``bias`` {turn_on, gauss_markov {sigma, tau}, random_walk}: the standard deviation of a
  constant drawn at start; a first-order Gauss-Markov process db = -b/tau dt + sigma dW
  (steady spread sigma sqrt(tau/2), Gazebo's convention); a random walk db = random_walk dW.
* ``range`` (peak acceleration): the output clips at +-range, and the clipped samples count.
* ``adc`` {bits, full_scale, noise}: DAQ noise (V rms), clipping at +-full_scale and rounding to
  the grid of 2 full_scale / 2^bits volts; needs ``sensitivity``.

Contract (what the loader produces)
-----------------------------------
``scene_model.scene['channel']`` is a *resolved channel*, and ``sensors[i]['channel']`` one or
None (the sensor states none). A resolved channel is a plain dict, SI, every key present, None
for a stage that is off::

    {'preset': str,                              # the preset it started from
     'sensitivity': float V/(m/s^2) or None,
     'sensitivity_error': [ex, ey, ez] or None,  # fractions
     'orientation': [roll, pitch, yaw] rad or None,
     'transverse': {'fraction': f, 'angle': rad} or None,
     'resonance': {'frequency': Hz, 'q': float} or None,
     'highpass': {'corner': Hz} or None,
     'noise_density': (m/s^2)/sqrt(Hz) or None,
     'bias': {'turn_on': m/s^2 or None,
              'gauss_markov': {'sigma': (m/s^2)/sqrt(s), 'tau': s} or None,
              'random_walk': (m/s^2)/sqrt(s) or None} or None,
     'range': m/s^2 or None,
     'adc': {'bits': int, 'full_scale': V, 'noise': V rms} or None}

:func:`.accelerometers.channel_of` gives the channel of the accelerometer at a node (its
sensors' channel, else the scene's), for the node, ``study record`` and ``study simulate``
(one code path).
Refused at load, one line each naming the key and its allowed range: an unknown preset
(naming the presets), an unknown stage key, a value out of range, ``adc`` without
``sensitivity``, both ``corner`` and ``time_constant``, two channels at one node, and a
mounted resonance not above the anti-alias band edge (the smallest ``lowpass`` the
accelerometer's sensors state; a sensor without one gets its cutoff at run time, where
:func:`.accelerometers.resonance_problem` gives the same message).

``channel=ideal`` as an override sets the top-level channel to the ideal one whatever the file
states (a preset name or a mapping); per-sensor channels are left as they are.
"""
from __future__ import annotations

import copy
import difflib
import math
from collections.abc import Iterator, Mapping
from typing import Any

from .containers import Optional, Section, Vector
from .schema import _INVALID, Choice, Field, Integer, KeyInfo, Quantity, _Errors, _got, _join

__all__ = ['STAGES', 'PRESETS', 'CHANNEL', 'SENSOR_CHANNEL', 'Channel', 'preset_channel']

#: Stage keys of a channel, in the order of the resolved dict and the key table (the chain's
#: order is the module notes' numbered list).
STAGES = ('sensitivity', 'sensitivity_error', 'orientation', 'transverse', 'resonance',
          'highpass', 'noise_density', 'bias', 'range', 'adc')

# --- presets ------------------------------------------------------------------------------
# Raw scene values, resolved through the stage keys below at import (a bad preset fails there).
# "notes" = ../shared/notes/sensor-channel.md (public datasheet facts gathered for issue 36).
_DAQ_24BIT = {'bits': 24,            # 24-bit delta-sigma (notes; NI-9234 family)
              'full_scale': '5 V',   # +-5 V input range (notes; NI-9234)
              'noise': '50 uV'}      # DAQ noise ~50 uV rms (notes: "about 0.5 mg" at 100 mV/g)
_DAQ_AC_COUPLING = {'corner': '0.5 Hz'}   # -3 dB near 0.27-0.5 Hz (notes): the sensor's
#                                          discharge time constant and the DAQ's AC coupling
#                                          (NI-9234: -3 dB at 0.5 Hz), one first-order stage

PRESETS = {
    # The model's signal as before the channel existed: every stage off.
    'ideal': {},
    # General-purpose IEPE accelerometer (100 mV/g, +-50 g: the PCB 352C33 class) on a 24-bit
    # +-5 V DAQ: 50 g x 100 mV/g fills the +-5 V input; LSB 0.6 uV = 6 ug.
    'iepe_100mv_50g': {
        'sensitivity': '100 mV/g',           # notes: 100 mV/g (tolerance +-5 to +-20 %)
        'range': '50 g',                     # notes: +-50 g peak
        'noise_density': '1.5 ug/sqrt(Hz)',  # notes: broadband resolution 0.00015 g rms over
        #                                      1 Hz-10 kHz = 150 ug / sqrt(9999 Hz)
        'highpass': _DAQ_AC_COUPLING,
        'resonance': {'frequency': '35 kHz',  # notes: mounted resonance 30-50 kHz
                      'q': 25},               # not on datasheets: gives the notes' in-band
        #                                       errors, +4 % at 0.2 fn, +10 % at 0.3 fn
        'transverse': {'fraction': '2 %'},    # datasheets: <= 5 % (notes); a typical
        #                                       calibration certificate reads 1-3 %
        'adc': _DAQ_24BIT,
    },
    # High-g IEPE accelerometer for impact-heavy casings (10 mV/g, +-500 g catalogue class),
    # same DAQ: 500 g x 10 mV/g fills the +-5 V input; LSB 60 ug, DAQ noise 5 mg rms.
    'iepe_10mv_500g': {
        'sensitivity': '10 mV/g',            # catalogue class: 10 mV/g, +-500 g peak
        'range': '500 g',
        'noise_density': '15 ug/sqrt(Hz)',   # the IEPE amplifier's noise in volts is about
        #                                      that of the 100 mV/g sensor: 10 x its density
        #                                      in g (catalogue class: ~0.002 g rms broadband)
        'highpass': _DAQ_AC_COUPLING,
        'resonance': {'frequency': '50 kHz',  # stiffer, lighter element: higher than the
                      'q': 25},               # 100 mV/g sensor's (notes' 30-50 kHz span top)
        'transverse': {'fraction': '2 %'},    # as the 100 mV/g sensor (<= 5 %)
        'adc': _DAQ_24BIT,
    },
    # MEMS accelerometer, +-16 g, digital 16-bit output (the TDK InvenSense ICM-42688-P:
    # +-2/4/8/16 g, 16-bit registers, 2048 LSB/g at +-16 g, 70 ug/sqrt(Hz)); DC response.
    'mems_16g': {
        'sensitivity': '1 V/g',              # equivalent: the digital output modelled as an
        #                                      ADC whose volts read g
        'range': '16 g',                     # ICM-42688-P full-scale +-16 g
        'noise_density': '70 ug/sqrt(Hz)',   # ICM-42688-P, low-noise mode
        'bias': {
            'turn_on': '20 mg',              # Gazebo/PX4 ADIS16448 default turn-on bias sigma
            #                                  20 mg; ICM-20948 zero-g tolerance +-25 mg
            'gauss_markov': {'sigma': '3e-3 m/s^2/sqrt(s)',   # Gazebo/PX4 (rotors_simulator)
                             'tau': '300 s'},                 # ADIS16448 defaults: "random
            #                                  walk" 2 x 3e-3 m/s^3/sqrt(Hz) (their factor 2
            #                                  left out), correlation time 300 s: steady
            #                                  spread 3e-3 sqrt(150) = 0.037 m/s^2 (3.7 mg)
        },
        'transverse': {'fraction': '2 %'},   # cross-axis sensitivity +-2 % (ICM-20948)
        'adc': {'bits': 16,                  # 16-bit output words
                'full_scale': '16 V',        # = 16 g at 1 V/g: LSB 32 g / 2^16 = 1/2048 g
                'noise': '0 V'},             # the part's noise is in noise_density
        # no highpass (DC response), no resonance (the proof mass's is beyond its own digital
        # low-pass, which is not modelled)
    },
}

# --- stage keys ----------------------------------------------------------------------------


def _check_highpass(values: dict[str, Any]) -> str | None:
    given = [k for k in ('corner', 'time_constant') if values[k] is not None]
    if len(given) != 1:
        return ("give exactly one of 'corner' and 'time_constant' "
                f"(got {', '.join(given) or 'neither'})")
    return None


_ANGLE: dict[str, Any] = dict(min='-180 deg', max='180 deg')

_STAGE_FIELDS = {
    'orientation': Vector('angle', 3, **_ANGLE, unit='deg',
                          doc='mounting: [roll, pitch, yaw] of the sensor axes in the model '
                              'frame, R = Rz(yaw) Ry(pitch) Rx(roll); the sensor reads R^T a'),
    'transverse': Section({
        'fraction': Quantity('dimensionless', min=0, max=0.2,
                             doc='transverse sensitivity: the fraction of the perpendicular '
                                 'acceleration each axis reads'),
        'angle': Quantity('angle', default='0 deg', **_ANGLE,
                          doc='direction of the most sensitive transverse axis: axis i reads '
                              'fraction (cos(angle) a_j + sin(angle) a_k), (i, j, k) cyclic'),
    }, doc='transverse (cross-axis) sensitivity'),
    'sensitivity_error': Vector('dimensionless', 3, min=-0.5, max=0.5,
                                doc='per-axis sensitivity error [x, y, z] (fractions): the '
                                    'published axis is scaled by 1 + error'),
    'resonance': Section({
        'frequency': Quantity('frequency', min=0, min_inclusive=False,
                              doc='mounted resonance frequency fn; must lie above the '
                                  'anti-alias band edge (the sensors\' lowpass)'),
        'q': Quantity('dimensionless', min=0.5, max=1000, min_inclusive=False,
                      doc='quality factor Q of the mounted resonance'),
    }, doc='mounted resonance: second-order low-pass (fn, Q), unit gain at DC'),
    'highpass': Section({
        'corner': Optional(Quantity('frequency', min=0, min_inclusive=False),
                           doc='-3 dB corner; give this or time_constant'),
        'time_constant': Optional(Quantity('time', min=0, min_inclusive=False),
                                  doc='discharge time constant tau, corner = 1/(2 pi tau); '
                                      'give this or corner'),
    }, checks=[_check_highpass], doc='first-order high-pass (IEPE discharge time constant, '
                                     'AC coupling); off = DC response'),
    'noise_density': Quantity('acceleration_density', min=0,
                              doc='sensor noise, white, per axis: the one-sided amplitude '
                                  'spectral density datasheets give, before the anti-alias '
                                  'filter'),
    'bias': Section({
        'turn_on': Optional(Quantity('acceleration', min=0),
                            doc='standard deviation of a constant bias drawn at start, per '
                                'axis; none = no turn-on bias'),
        'gauss_markov': Optional(Section({
            'sigma': Quantity('acceleration_per_sqrt_time', min=0,
                              doc='driving strength: steady spread sigma sqrt(tau/2)'),
            'tau': Quantity('time', min=0, min_inclusive=False, doc='correlation time'),
        }), doc='first-order Gauss-Markov bias (bias instability); none = off'),
        'random_walk': Optional(Quantity('acceleration_per_sqrt_time', min=0),
                                doc='bias random walk (Allan slope +1/2); none = off'),
    }, doc='slowly varying bias per axis (MEMS-style terms)'),
    'range': Quantity('acceleration', min=0, min_inclusive=False,
                      doc='measuring range (peak): the output clips at +-range'),
    'sensitivity': Quantity('sensitivity', min=0, min_inclusive=False,
                            doc='nominal sensitivity (acceleration to volts), the one the DAQ '
                                'divides by'),
    'adc': Section({
        'bits': Integer(min=8, max=32, doc='ADC resolution'),
        'full_scale': Quantity('voltage', min=0, min_inclusive=False,
                               doc='ADC input range (peak): clips at +-full_scale; LSB = 2 '
                                   'full_scale / 2^bits'),
        'noise': Quantity('voltage', default='0 V', min=0,
                          doc='DAQ noise (rms), after the anti-alias filter'),
    }, doc='the DAQ\'s ADC: every published sample on its grid; needs sensitivity'),
}

_PRESET_NAMES = tuple(PRESETS)
_KEYS = Section({'preset': Choice(_PRESET_NAMES, default='ideal',
                                  doc='the preset the stages start from'),
                  **{stage: _STAGE_FIELDS[stage] for stage in STAGES}})


def _preset_problem(name: object) -> str:
    presets = ' | '.join(_PRESET_NAMES)
    if not isinstance(name, str):
        return f'expected a channel preset name, {_got(name)}; use one of {presets}'
    close = ([p for p in _PRESET_NAMES if name and p.startswith(name)]
             or difflib.get_close_matches(name, _PRESET_NAMES, n=1, cutoff=0.5))
    hint = f"did you mean {' or '.join(repr(c) for c in close)}? " if close else ''
    return f'{name!r} is not a channel preset; {hint}use one of {presets}'


def _finish(stage: str, value: Any) -> Any:
    """The resolved form of one valid converted stage value."""
    if stage == 'highpass':
        corner = value['corner']
        if corner is None:
            corner = 1.0 / (2.0 * math.pi * value['time_constant'])
        return {'corner': corner}
    if stage == 'bias' and all(v is None for v in value.values()):
        return None   # an empty bias mapping is no bias
    return value


def _over(preset_value: object, given: object) -> object:
    """A stage mapping ``given`` over the preset's, key by key (nested mappings too); a
    non-mapping on either side is ``given`` as it is."""
    if not isinstance(preset_value, dict) or not isinstance(given, dict):
        return given
    out = dict(preset_value)
    for key, value in given.items():
        out[key] = None if value is None else _over(preset_value.get(key), value)
    return out


def _resolve(raw: dict[str, Any], path: str, errors: _Errors,
             presets: Mapping[str, dict[str, Any]]) -> Any:
    """Resolve a channel mapping against ``presets`` (name -> resolved); _INVALID on errors."""
    before = len(errors)
    for key in raw:
        if key not in _KEYS.fields:
            errors.add(_join(path, key), _KEYS._unknown(key))
    name = raw.get('preset', 'ideal')
    if not isinstance(name, str) or name not in presets:
        errors.add(_join(path, 'preset'), _preset_problem(name))
        name, base = None, None
    else:
        base = presets[name]
    out = {'preset': name}
    for stage in STAGES:
        if stage not in raw:
            out[stage] = copy.deepcopy(base[stage]) if base is not None else None
        elif raw[stage] is None:
            out[stage] = None   # 'stage: null' switches the preset's stage off
        else:
            at = len(errors)
            given = raw[stage]
            if name is not None and stage != 'highpass':   # highpass: one of two keys
                given = _over(PRESETS.get(name, {}).get(stage), given)
            value = _STAGE_FIELDS[stage].resolve(True, given, _join(path, stage), errors)
            out[stage] = _finish(stage, value) if len(errors) == at else _INVALID
    if len(errors) > before:
        return _INVALID
    if out['adc'] is not None and out['sensitivity'] is None:
        errors.add(_join(path, 'adc'), 'needs a sensitivity to turn acceleration into volts '
                   "(sensitivity is off); give 'sensitivity' (e.g. 100 mV/g) or adc: null")
        return _INVALID
    return out


def _resolve_presets() -> dict[str, dict[str, Any]]:
    off = {'preset': 'ideal', **{stage: None for stage in STAGES}}
    resolved = {}
    for name, raw in PRESETS.items():
        errors = _Errors()
        value = _resolve(raw, f'preset {name}', errors, {'ideal': off})
        if errors:
            raise ValueError('; '.join(errors.lines()))
        value['preset'] = name
        resolved[name] = value
    return resolved


_RESOLVED = _resolve_presets()


def preset_channel(name: str) -> dict[str, Any]:
    """Return the resolved channel of a preset.

    Parameters
    ----------
    name : str
        A key of :data:`PRESETS`.

    Returns
    -------
    dict
        A fresh resolved channel (see the module notes), SI.

    Raises
    ------
    KeyError
        For an unknown preset, naming the presets.
    """
    if name not in _RESOLVED:
        raise KeyError(_preset_problem(name))
    return copy.deepcopy(_RESOLVED[name])


# --- the field ------------------------------------------------------------------------------

class Channel(Field):
    """A channel key: a preset name or a mapping of ``preset`` and stage keys.

    Converts to a resolved channel (see the module notes).

    Parameters
    ----------
    default : str or None
        ``'ideal'`` (the top-level key) or ``None`` (a sensor's: none = the scene's channel).
    doc : str
        Description.
    rows : bool, optional
        List the preset and stage keys below this key in the key table (once is enough:
        ``sensors[].channel`` refers to ``channel``'s).
    """

    def __init__(self, default: str | None, doc: str, rows: bool = True) -> None:
        super().__init__(default, doc)
        self.rows = rows
        self._check_default()

    def kind(self) -> str:
        return 'preset or section'

    def range_text(self) -> str:
        return f'{" | ".join(_PRESET_NAMES)}, or a mapping'

    def expects(self) -> str:
        return (f'a channel preset ({" | ".join(_PRESET_NAMES)}) or a mapping of preset and '
                f'stage keys ({", ".join(_KEYS.fields)})')

    def _subfields(self) -> tuple[Field, ...]:
        return tuple(_STAGE_FIELDS[stage] for stage in STAGES)

    def _convert(self, raw: object, path: str, errors: _Errors) -> object:
        if isinstance(raw, str):
            if raw not in _RESOLVED:
                errors.add(path, _preset_problem(raw))
                return _INVALID
            return copy.deepcopy(_RESOLVED[raw])
        if not isinstance(raw, dict):
            errors.add(path, f'expected {self.expects()}; {_got(raw)}')
            return _INVALID
        return _resolve(raw, path, errors, _RESOLVED)

    def _child_rows(self, path: str) -> Iterator[KeyInfo]:
        if not self.rows:
            return
        yield from _KEYS.fields['preset']._rows(_join(path, 'preset'))
        for stage in STAGES:
            rows = list(_STAGE_FIELDS[stage]._rows(_join(path, stage)))
            yield rows[0]._replace(default='preset')
            yield from rows[1:]


#: ``channel``: every accelerometer of the scene.
CHANNEL = Channel('ideal', doc='the accelerometer channel (sensor and DAQ) of every '
                               'accelerometer: a preset, or a mapping of preset and stage '
                               'keys; a stage key overrides the preset\'s stage key by key, '
                               'null switches it off (docs/scenes.md, "Accelerometer '
                               'channel")')
#: ``sensors[].channel``: the accelerometer at that sensor's node.
SENSOR_CHANNEL = Channel(None, rows=False,
                         doc='the channel of the accelerometer at this sensor\'s node, with '
                             'the keys of channel; the sensors of one node that state one '
                             'must state the same; none = the scene\'s channel')
