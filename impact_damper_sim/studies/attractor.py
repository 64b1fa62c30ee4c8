"""Where does an SDOF impact damper settle from rest? Our methods against the closed form.

The Masri-Caughey system (:mod:`impact_damper_sim.dampers.analytic`): housing ``M`` on a
spring ``K`` (damping ratio ``zeta``), force ``F0 cos(Omega t)``, impactor ``mu M`` in a slot
of travel ``D``, restitution ``e``. A point of the study is ``(r, zeta, mu, e, d)`` with
``r = Omega/omega_n`` and ``d = D K/F0``. Every run starts from rest (housing at rest at
``x = 0``, impactor at rest at the slot centre), as a user's simulation does.

What a run returns is what the comparison needs and nothing that depends on the sampling:
the peak ``|x|`` of each forcing period, and every impact (time, wall, approach speed) and
every stick. :func:`classify` names the long-run state against the symmetric two-impact
orbit (``'orbit'``, ``'other'``, ``'no_impacts'``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..dampers.analytic import symmetric_two_impact_orbits
from ..dampers.impactors import Impactor
from ..integrate.events import EVENT_KINDS, IMPACT
from ..integrate.forcing import Forcing, Harmonic
from ..integrate.model import LinearModel

__all__ = ['MASS', 'STIFFNESS', 'FORCE', 'AttractorRun', 'stable_orbit', 'sdof_system',
           'run_from_rest', 'classify', 'first_divergence', 'capture_period',
           'reference_impacts', 'min_wall_distance', 'orbit_deviation']

#: Housing mass (kg), spring (N/m) and force amplitude (N) of every study point (the values of
#: ``test_analytic_sdof``; results scale with ``F0/K``).
MASS = 2.0
STIFFNESS = 5.0e4
FORCE = 10.0

_STICK = EVENT_KINDS.index('stick')


@dataclass
class AttractorRun:
    """One run from rest.

    Attributes
    ----------
    point : tuple
        ``(r, zeta, mu, e, d)`` (-).
    method : str
        Method label.
    period : float
        Forcing period (s).
    amplitudes : ndarray
        Peak ``|x|`` over each forcing period, sampled at ``per_cycle`` points a period (m).
    impacts : ndarray, shape (k, 3)
        Time (s), wall (+1/-1) and approach speed ``v_n`` (m/s) of each impact.
    sticks : ndarray
        Times of the sticks (s).
    tail_t, tail_x : ndarray
        Sample times (s) and housing displacements (m) of the last forcing period.
    """

    point: tuple
    method: str
    period: float
    amplitudes: np.ndarray
    impacts: np.ndarray
    sticks: np.ndarray
    tail_t: np.ndarray = None
    tail_x: np.ndarray = None

    def late_amplitude(self, periods=10):
        """Largest per-period peak over the last ``periods`` periods (m)."""
        return float(np.max(self.amplitudes[-periods:]))


def _params(point):
    r, zeta, mu, e, d = (float(v) for v in point)
    wn = np.sqrt(STIFFNESS / MASS)
    return dict(M=MASS, K=STIFFNESS, c=2.0 * zeta * np.sqrt(STIFFNESS * MASS), F0=FORCE,
                Omega=r * wn, mass_ratio=mu, cor=e, clearance=d * FORCE / STIFFNESS)


def stable_orbit(point):
    """The stable symmetric two-impact orbit at ``point``, or ``None`` if there is none.

    Parameters
    ----------
    point : tuple
        ``(r, zeta, mu, e, d)`` (-).

    Returns
    -------
    SymmetricTwoImpactOrbit or None
        With its amplitude (m) and Floquet multipliers (-).
    """
    orbits = [o for o in symmetric_two_impact_orbits(**_params(point)) if o.stable]
    return orbits[0] if orbits else None


def sdof_system(point, offset=0.0, velocity=0.0):
    """The one-mode modal model and forcing of ``point`` (``q = sqrt(M) x``).

    Parameters
    ----------
    point : tuple
        ``(r, zeta, mu, e, d)`` (-).
    offset : float
        Initial impactor position relative to the slot centre (m); 0 is the rest start.
    velocity : float
        Initial impactor velocity (m/s).

    Returns
    -------
    model : LinearModel
        One mode, ``q = sqrt(M) x``, with the impactor (SI).
    forcing : Forcing
        ``F0 cos(Omega t)`` on the housing (N).
    omega : float
        Forcing frequency (rad/s).
    """
    p = _params(point)
    zeta = float(point[1])
    wn = np.sqrt(STIFFNESS / MASS)
    s = 1.0 / np.sqrt(MASS)
    imp = Impactor(name='i', kind='sdof', mass=p['mass_ratio'] * MASS, cor=p['cor'],
                   clearance=p['clearance'], rows=[[s]], housing_mass=MASS,
                   position=[float(offset)], velocity=[float(velocity)])
    model = LinearModel(M=[[1.0]], C=[[2 * zeta * wn]], K=[[wn * wn]], B=[[s]], sensors=[[s]],
                        impactors=[imp])
    return model, Forcing(1, [Harmonic(0, FORCE, p['Omega'])]), p['Omega']


def run_from_rest(point, periods, method='exact', per_cycle=400, chunk=200, offset=0.0,
                  **options):
    """Integrate ``point`` from rest over ``periods`` forcing periods.

    Parameters
    ----------
    point : tuple
        ``(r, zeta, mu, e, d)`` (-).
    periods : int
        Forcing periods to run (-).
    method : {'exact', 'newmark'}
        :class:`~impact_damper_sim.integrate.exact.ExactPropagator` or located-impact
        :class:`~impact_damper_sim.integrate.newmark.NewmarkIntegrator`.
    per_cycle : int
        Output steps per forcing period (-); Newmark's time step is ``period/per_cycle``.
    chunk : int
        Periods per ``advance`` call (-), to bound memory.
    offset : float
        Initial impactor offset from the slot centre (m): a tiny one probes how sensitive
        the transient is to its start.
    **options
        Passed to the integrator (``stick_rule``, ``substeps``, ...).

    Returns
    -------
    AttractorRun
        Per-period peaks (m), impacts (s, -, m/s), sticks (s) and the last period (s, m).
    """
    model, forcing, omega = sdof_system(point, offset)
    period = 2.0 * np.pi / omega
    if method == 'exact':
        from ..integrate.exact import ExactPropagator as cls
        options.setdefault('ledger', False)
    elif method == 'newmark':
        from ..integrate.newmark import NewmarkIntegrator as cls
        options.setdefault('ledger', False)
    else:
        raise ValueError(f"method must be 'exact' or 'newmark', got {method!r}")
    prop = cls(model, forcing, dt=period / per_cycle, **options)
    amps, evs = [], []
    done = 0
    while done < periods:
        n = min(chunk, periods - done)
        s = prop.advance(n * per_cycle)
        amps.append(np.abs(s.displacement[:, 0]).reshape(n, per_cycle).max(axis=1))
        evs.append(prop.take_events())
        done += n
    ev = np.concatenate(evs) if evs else np.zeros(0)
    imp = ev[ev['kind'] == IMPACT]
    impacts = np.column_stack([imp['t'], np.sign(imp['normal'][:, 0]), imp['v_n']]) \
        if imp.size else np.zeros((0, 3))
    label = method + ''.join(f' {k}={v}' for k, v in sorted(options.items()) if k != 'ledger')
    return AttractorRun(tuple(point), label, period, np.concatenate(amps), impacts,
                        ev['t'][ev['kind'] == _STICK], s.t[-per_cycle:],
                        s.displacement[-per_cycle:, 0])


def orbit_deviation(run, orbit):
    """Largest ``|x - x_orbit|`` over the run's last period, over the orbit amplitude.

    Parameters
    ----------
    run : AttractorRun
        The run (its last period of samples).
    orbit : SymmetricTwoImpactOrbit
        The closed-form orbit.

    Returns
    -------
    float
        The deviation (-).
    """
    from ..dampers.analytic_flow import orbit_state
    return float(np.max(np.abs(run.tail_x - orbit_state(orbit, run.tail_t)[0]))
                 / orbit.amplitude)


def classify(amplitudes, orbit, periods=10, rel=1e-3):
    """Name the long-run state of a run.

    Parameters
    ----------
    amplitudes : ndarray
        Per-period peaks (m).
    orbit : SymmetricTwoImpactOrbit or None
        The stable orbit (or ``None``).
    periods : int
        Trailing periods examined (-).
    rel : float
        Relative tolerance on the amplitude, max and min over the trailing periods (-).

    Returns
    -------
    str
        ``'orbit'`` if every trailing peak is within ``rel`` of the orbit's amplitude,
        otherwise ``'other'``.
    """
    if orbit is None:
        return 'other'
    tail = np.asarray(amplitudes[-periods:]) / orbit.amplitude
    return 'orbit' if np.all(np.abs(tail - 1.0) < rel) else 'other'


def first_divergence(a, b, rel=1e-3):
    """Index of the first impact where two runs part, and the time of it.

    Two impact sequences agree at impact ``k`` if the walls are equal and the times differ by
    less than ``rel`` of the forcing period ``a.period``.

    Parameters
    ----------
    a, b : AttractorRun
        The runs (same point, same start).
    rel : float
        Tolerance on the impact times, as a fraction of the forcing period (-).

    Returns
    -------
    (int, float)
        The index and the time (s) of the first disagreement; ``(n, nan)`` if the first ``n``
        common impacts all agree.
    """
    n = min(len(a.impacts), len(b.impacts))
    for k in range(n):
        ta, wa, _ = a.impacts[k]
        tb, wb, _ = b.impacts[k]
        if wa != wb or abs(ta - tb) > rel * a.period:
            return k, float(min(ta, tb))
    return n, float('nan')


def capture_period(amplitudes, orbit, rel=1e-3):
    """First forcing period from which every later peak is within ``rel`` of the orbit.

    Parameters
    ----------
    amplitudes : ndarray
        Per-period peaks (m).
    orbit : SymmetricTwoImpactOrbit
        The stable orbit.
    rel : float
        Relative tolerance (-).

    Returns
    -------
    int or None
        The period index, or ``None`` if the run ends off the orbit (censored).
    """
    off = np.flatnonzero(np.abs(np.asarray(amplitudes) / orbit.amplitude - 1.0) >= rel)
    if off.size and off[-1] >= len(amplitudes) - 10:
        return None
    return int(off[-1] + 1) if off.size else 0


def reference_impacts(point, n_impacts, rtol=1e-12):
    """Impacts from rest by scipy's DOP853 with terminal wall events (independent reference).

    A restart after every impact, the impact law applied by hand. Like every sign-change
    event finder it misses a contact whose dip and return fit inside one solver step (a
    grazing contact): compare with it only up to the first graze.

    Parameters
    ----------
    point : tuple
        ``(r, zeta, mu, e, d)`` (-).
    n_impacts : int
        Impacts to compute (-).
    rtol : float
        Relative tolerance of DOP853 (-).

    Returns
    -------
    ndarray, shape (n_impacts, 7)
        Time (s), wall (+1/-1), approach speed (m/s), then the post-impact state
        ``(x, x', z, z')`` (m, m/s, m, m/s).
    """
    from scipy.integrate import solve_ivp
    p = _params(point)
    M, K, c, F0, om = p['M'], p['K'], p['c'], p['F0'], p['Omega']
    mu, e, D = p['mass_ratio'], p['cor'], p['clearance']

    def rhs(t, y):
        return [y[1], (F0 * np.cos(om * t) - c * y[1] - K * y[0]) / M, y[3], 0.0]

    def upper(t, y):
        return y[2] - y[0] - D / 2.0

    def lower(t, y):
        return y[2] - y[0] + D / 2.0

    upper.terminal, upper.direction = True, 1.0
    lower.terminal, lower.direction = True, -1.0
    T = 2.0 * np.pi / om
    atol = 1e-16 * np.array([D, D * om, D, D * om])
    t, y, out = 0.0, np.zeros(4), []
    while len(out) < n_impacts:
        sol = solve_ivp(rhs, (t, t + 4.0 * T), y, method='DOP853', rtol=rtol, atol=atol,
                        events=(upper, lower))
        if sol.status != 1:
            break
        k = 0 if sol.t_events[0].size else 1
        te, pre = sol.t_events[k][0], sol.y_events[k][0]
        wall = 1.0 if k == 0 else -1.0
        xd = ((1 - mu * e) * pre[1] + mu * (1 + e) * pre[3]) / (1 + mu)
        zd = ((1 + e) * pre[1] + (mu - e) * pre[3]) / (1 + mu)
        y = np.array([pre[0], xd, pre[0] + wall * D / 2.0, zd])
        out.append((te, wall, wall * (pre[3] - pre[1]), *y))
        t = te
    return np.array(out)


def min_wall_distance(point, state, t0, duration, wall=-1.0, n=200001):
    """Smallest distance to a wall along the closed-form free flight from a post-impact state.

    Parameters
    ----------
    point : tuple
        ``(r, zeta, mu, e, d)`` (-).
    state : array_like
        ``(x, x', z, z')`` just after an impact at ``t0`` (m, m/s, m, m/s).
    t0 : float
        Time of that state (s).
    duration : float
        Flight examined (s), excluding the first 1 % (the wall just left).
    wall : float
        +1 or -1: which wall (-).
    n : int
        Grid points (-).

    Returns
    -------
    (float, float)
        The smallest signed distance (m; negative = the impactor is through the wall, i.e.
        a contact the flight must have had) and its time (s).
    """
    from ..dampers.analytic_flow import _Oscillator
    p = _params(point)
    osc = _Oscillator(p['M'], p['K'], p['c'], p['F0'], p['Omega'])
    x0, v0, z0, w0 = (float(s) for s in state)
    ts = np.linspace(t0 + 0.01 * duration, t0 + duration, n)
    x, _ = osc.flow(t0, x0, v0, ts)
    rel = z0 + w0 * (ts - t0) - x
    dist = p['clearance'] / 2.0 - wall * rel
    i = int(np.argmin(dist))
    return float(dist[i]), float(ts[i])
