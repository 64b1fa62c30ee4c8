"""The keys of an accelerometer channel's spec and their check, before a chain is built.

:func:`resolve_spec` gives :class:`~impact_damper_sim.live.channel.SensorChannel` its spec
with every key of :data:`SPEC_KEYS` (None = stage off) and refuses the values the chain
cannot take, each message naming its key. Everything is SI.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

#: Keys of the resolved spec, all present in the scene loader's output (None = off).
SPEC_KEYS = ('preset', 'sensitivity', 'sensitivity_error', 'orientation', 'transverse',
             'resonance', 'highpass', 'noise_density', 'bias', 'range', 'adc')


def resolve_spec(spec: Mapping[str, Any] | None, msg: Callable[[str], str]) -> dict[str, Any]:
    """The spec with every key (None = off), checked for the values the chain relies on.

    Parameters
    ----------
    spec : mapping or None
        The sensor spec (SI, keys of :data:`SPEC_KEYS`), or None for the ideal channel.
    msg : callable
        Turns a problem's text into the error message (naming the channel).

    Returns
    -------
    dict
        Every key of :data:`SPEC_KEYS`, values as floats (SI) or None.

    Raises
    ------
    ValueError
        An unknown key or a value the chain cannot take; the message names the key.
    """
    if spec is None:
        return {k: None for k in SPEC_KEYS}
    unknown = sorted(set(spec) - set(SPEC_KEYS))
    if unknown:
        raise ValueError(msg(f"unknown spec key(s) {', '.join(map(repr, unknown))}; "
                             f"known: {', '.join(SPEC_KEYS)}"))
    s: dict[str, Any] = {k: spec.get(k) for k in SPEC_KEYS}

    def positive(key: str, value: Any, zero_ok: bool = False) -> float:
        v = float(value)
        if not (math.isfinite(v) and (v >= 0 if zero_ok else v > 0)):
            raise ValueError(msg(f"spec key {key!r}: must be finite and "
                                 f"{'>=' if zero_ok else '>'} 0, got {value!r}"))
        return v

    if s['sensitivity'] is not None:
        s['sensitivity'] = positive('sensitivity', s['sensitivity'])
    for key in ('sensitivity_error', 'orientation'):
        if s[key] is not None:
            v = [float(x) for x in s[key]]
            if len(v) != 3 or not all(map(math.isfinite, v)):
                raise ValueError(msg(f'spec key {key!r}: must be 3 finite numbers, '
                                     f'got {s[key]!r}'))
            if key == 'sensitivity_error' and min(v) <= -1:
                raise ValueError(msg(f"spec key 'sensitivity_error': must be > -1 per axis, "
                                     f'got {v}'))
            s[key] = v
    if s['transverse'] is not None:
        t = s['transverse']
        s['transverse'] = {'fraction': positive('transverse.fraction', t['fraction'], True),
                           'angle': float(t['angle'])}
    if s['resonance'] is not None:
        s['resonance'] = {'frequency': float(s['resonance']['frequency']),
                          'q': float(s['resonance']['q'])}
    if s['highpass'] is not None:
        s['highpass'] = {'corner': float(s['highpass']['corner'])}
    if s['noise_density'] is not None:
        s['noise_density'] = positive('noise_density', s['noise_density'], True)
    if s['bias'] is not None:
        b = dict(s['bias'])
        out: dict[str, Any] = {'turn_on': None, 'gauss_markov': None, 'random_walk': None}
        extra = sorted(set(b) - set(out))
        if extra:
            raise ValueError(msg(f"unknown spec key(s) {', '.join(f'bias.{k}' for k in extra)}"
                                 f'; known: bias.turn_on, bias.gauss_markov, bias.random_walk'))
        if b.get('turn_on') is not None:
            out['turn_on'] = positive('bias.turn_on', b['turn_on'], True)
        if b.get('gauss_markov') is not None:
            gm = b['gauss_markov']
            out['gauss_markov'] = {
                'sigma': positive('bias.gauss_markov.sigma', gm['sigma'], True),
                'tau': positive('bias.gauss_markov.tau', gm['tau'])}
        if b.get('random_walk') is not None:
            out['random_walk'] = positive('bias.random_walk', b['random_walk'], True)
        s['bias'] = out
    if s['range'] is not None:
        s['range'] = positive('range', s['range'])
    if s['adc'] is not None:
        if s['sensitivity'] is None:
            raise ValueError(msg("spec key 'adc' needs 'sensitivity' (V per m/s^2) to map "
                                 'volts to acceleration; none given'))
        adc = s['adc']
        bits = adc['bits']
        if int(bits) != bits or not 1 <= int(bits) <= 32:
            raise ValueError(msg(f"spec key 'adc.bits': must be a whole number in [1, 32], "
                                 f'got {bits!r}'))
        s['adc'] = {'bits': int(bits), 'full_scale': positive('adc.full_scale',
                                                               adc['full_scale']),
                    'noise': positive('adc.noise', adc['noise'], True)}
    return s


__all__ = ['SPEC_KEYS', 'resolve_spec']
