"""Which modes a scene keeps: its frequencies of interest, the automatic cutoff and the
modal basis with the scene's damping.

:func:`excitation_frequencies` lists the sensor low-pass cutoffs, the forcing frequencies and
the rotor speed; :func:`auto_cutoff` makes ``f_max`` of ``modal.cutoff: auto`` from them;
:func:`_build_basis` reduces the assembled system to the retained modes with the scene's tare
damping, naming the scene key of any problem. :data:`MIN_SAMPLES_PER_REVOLUTION` bounds the
sample period of a sampled unbalance force. Kept apart from :mod:`.build` because it needs the
assembled system and the validated scene only.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from .schema import _Errors

if TYPE_CHECKING:
    from ..fem.system import AssembledSystem
    from ..modal import ModalBasis

__all__ = ['MIN_SAMPLES_PER_REVOLUTION', 'auto_cutoff', 'excitation_frequencies']


#: Samples per rotor revolution at least when the unbalance force is sampled (first-order
#: hold of a rotation at N samples per revolution: amplitude sinc^2(pi/N), 3.3 % low at 10)
MIN_SAMPLES_PER_REVOLUTION = 10


def excitation_frequencies(scene: dict[str, Any],
                           first_hz: float | None = None) -> list[tuple[str, float]]:
    """The frequencies of interest of a scene, for ``modal.cutoff: auto``.

    Parameters
    ----------
    scene : dict
        A validated scene (SI units).
    first_hz : float, optional
        First natural frequency of the structure (Hz), needed only for forcing given by
        ``frequency_ratio``.

    Returns
    -------
    list of (str, float)
        ``(source, frequency in Hz)``: each sensor low-pass cutoff, each forcing frequency and
        the highest rotor speed over 2 pi (rev/s); a ``commanded`` speed counts with its
        initial speed, a ``paper_ramp`` without ``final_speed`` with the paper's 2400 rad/s.
    """
    out = [(f"sensor {s['name']} low-pass", s['lowpass']) for s in scene['sensors']
           if s['lowpass'] is not None]
    for i, f in enumerate(scene['forcing']):
        hz = f['frequency'] if f['frequency'] is not None else f['frequency_ratio'] * first_hz
        out.append((f'forcing[{i}]', hz))
    rotor = scene['rotor']
    if rotor is not None:
        sp = rotor['speed']
        kind = sp['kind']
        if kind == 'constant':
            omega = sp['speed']
        elif kind == 'paper_ramp':
            omega = sp['final_speed'] if sp['final_speed'] is not None else 2400.0
        elif kind == 'piecewise':
            omega = max(sp['speeds'])
        else:
            omega = sp['speed']
        label = 'initial commanded rotor speed' if kind == 'commanded' else 'max rotor speed'
        if omega > 0:
            out.append((label, omega / (2.0 * np.pi)))
    return out


def auto_cutoff(system: AssembledSystem, scene: dict[str, Any],
                method: str = 'auto') -> tuple[float, str]:
    """The ``f_max`` of ``modal.cutoff: auto`` and why.

    ``f_max = cutoff_factor * max(f)`` over :func:`excitation_frequencies`: modes above the
    measured band and the excitation respond quasi-statically and are dropped; the factor
    keeps the modes just above the band, whose static tail the sensors still see.

    Parameters
    ----------
    system : AssembledSystem
        The structure (for the first natural frequency, if a forcing is given as a ratio).
    scene : dict
        A validated scene (SI units).
    method : str
        Eigen solver for the first mode (see :func:`~impact_damper_sim.modal.modal_reduction`).

    Returns
    -------
    f_max : float
        Cutoff (Hz).
    reason : str
        Human readable: the governing source, its frequency and the factor.

    Raises
    ------
    ValueError
        No sensor low-pass, forcing or rotor to derive a cutoff from.
    """
    from ..modal import modal_reduction
    first = None
    if any(f['frequency'] is None for f in scene['forcing']):
        first = float(modal_reduction(system, n_modes=1, method=method).frequencies_hz[0])
    sources = excitation_frequencies(scene, first)
    if not sources:
        raise ValueError('cutoff: auto needs a sensor low-pass, a forcing frequency or a rotor '
                         'speed to derive f_max from; give modal.f_max or modal.n_modes')
    label, top = max(sources, key=lambda item: item[1])
    factor = scene['modal']['cutoff_factor']
    return factor * top, (f'cutoff auto: f_max = {factor:g} x {top:.6g} Hz ({label}, the '
                          f'highest of {len(sources)} frequencies of interest) = '
                          f'{factor * top:.6g} Hz')


def _build_basis(system: AssembledSystem, modal: dict[str, Any], source: str | None,
                 scene: dict[str, Any]) -> ModalBasis:
    from dataclasses import replace

    from ..modal import modal_reduction
    errors = _Errors()
    f_max, auto_reason = modal['f_max'], None
    if modal.get('cutoff') == 'auto':
        try:
            f_max, auto_reason = auto_cutoff(system, scene, modal['solver'])
        except ValueError as exc:
            errors.add('modal.cutoff', str(exc))
        errors.raise_if_any(source)
    kwargs = dict(n_modes=modal['n_modes'], f_max=f_max,
                  zeta=modal['damping']['default'], method=modal['solver'])
    try:
        basis = modal_reduction(system, **kwargs)
    except ValueError as exc:
        message = str(exc)
        # a selection problem names its key; anything else is the structure's (a mechanism)
        key = next((f'modal.{k}' for k in ('n_modes', 'f_max') if message.startswith(k)),
                   'structure')
        if key == 'modal.f_max' and auto_reason:
            key, message = 'modal.cutoff', f'{message} ({auto_reason})'
        errors.add(key, message)
    errors.raise_if_any(source)
    if auto_reason:
        basis = replace(basis, selection_reason=f'{basis.selection_reason}; {auto_reason}')
    per_mode = modal['damping']['modes']
    for mode in sorted(per_mode):
        if mode > basis.n_modes:
            errors.add(f'modal.damping.modes.{mode}', f'mode {mode} is not retained '
                       f'({basis.selection_reason})')
    errors.raise_if_any(source)
    if per_mode:
        # the scene numbers modes from 1, modal_reduction from 0
        overrides = {mode - 1: ratio for mode, ratio in per_mode.items()}
        basis = modal_reduction(system, zeta_overrides=overrides, **kwargs)
        if auto_reason:
            basis = replace(basis, selection_reason=f'{basis.selection_reason}; {auto_reason}')
    return basis
