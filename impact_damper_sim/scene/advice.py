"""Which scene settings to change when a run diverges (:func:`scene_advice`).

:class:`~impact_damper_sim.integrate.divergence.Divergence` says what diverged and when; the
advice reads the scene (its keys, SI values and linear stability) to name the setting: the
cross-coupled stiffness of a linearly unstable structure, the largest forcing amplitude, the
rotor's unbalance, the restitution or sample period for chatter.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..integrate.divergence import Divergence
    from .build import SceneModel


def scene_advice(scene: SceneModel, cause: Divergence | None = None) -> str:
    """Which settings to change when ``scene`` diverges (one line).

    Parameters
    ----------
    scene : SceneModel
        The built scene (its ``scene`` dict, SI units, and modal matrices are read).
    cause : Divergence, optional
        The divergence (chatter gets its own advice).

    Returns
    -------
    str
        E.g. ``"change forcing.0.amplitude (1e+300 N)"``; the linearly unstable case names
        the cross-coupled stiffness and its growth rate.
    """
    cfg = scene.scene
    hints: list[str] = []
    couplings = (cfg.get('structure') or {}).get('cross_couplings') or []
    if couplings:
        growth = _linear_growth(scene)
        if growth is not None and growth > 0:
            keys = ', '.join(f'structure.cross_couplings.{i}.kcc ({c["kcc"]:.4g} N/m)'
                             for i, c in enumerate(couplings))
            # the cause, whatever else the scene has
            return (f'the structure is linearly unstable (growth rate {growth:.3g} 1/s): '
                    f'lower {keys}')
    forcing = cfg.get('forcing') or []
    if forcing:
        j = max(range(len(forcing)), key=lambda i: forcing[i]['amplitude'])
        hints.append(f'forcing.{j}.amplitude ({forcing[j]["amplitude"]:.4g} N)')
    rotor = cfg.get('rotor') or {}
    if rotor.get('unbalance'):
        mult = rotor.get('multiplier', 1.0)
        hints.append(f'rotor.multiplier ({mult:.4g}) or rotor.unbalance[].amount')
    if cause is not None and 'chatter' in cause.what and cfg.get('impactors'):
        hints.append('impactors[].cor or simulation.dt (bounce-down chatter)')
    if not hints:
        hints.append('the stiffness and damping values (structure.*) and simulation.dt')
    return 'change ' + ', '.join(hints)


def _linear_growth(scene: SceneModel) -> float | None:

    """Largest real part of the scene's linear eigenvalues without impactors (1/s)."""
    try:
        from ..modal.stability import least_damped_eigenvalue
        return float(least_damped_eigenvalue(scene.basis.stiffness_matrix(),
                                             scene.basis.damping_matrix()).real)
    except Exception:   # advice only: a failure here must not hide the divergence
        return None


__all__ = ['scene_advice']
