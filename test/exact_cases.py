"""Small hand-built models shared by the integrator tests (SI units)."""
import numpy as np

from impact_damper_sim.dampers.impactors import Impactor
from impact_damper_sim.integrate.forcing import Forcing, Harmonic
from impact_damper_sim.integrate.model import LinearModel


def sdof_model(mass=2.0, stiffness=5e4, zeta=0.0, impactor=None):
    """Primary mass on a spring as a one-mode modal model (q = sqrt(mass) x).

    Parameters
    ----------
    mass : float
        Primary mass (kg).
    stiffness : float
        Spring (N/m).
    zeta : float
        Damping ratio (dimensionless).
    impactor : dict, optional
        Keyword arguments of :class:`Impactor` except ``rows``.
    """
    wn = np.sqrt(stiffness / mass)
    r = 1.0 / np.sqrt(mass)
    imps = [] if impactor is None else [Impactor(rows=[[r]], housing_mass=mass, **impactor)]
    return LinearModel(M=[[1.0]], C=[[2 * zeta * wn]], K=[[wn * wn]], B=[[r]], sensors=[[r]],
                       impactors=imps)


def planar_model(mass=2.0, stiffness=5e4, zeta=0.0, impactor=None):
    """Isotropic 2-DOF (y, z) primary mass as a two-mode modal model."""
    wn = np.sqrt(stiffness / mass)
    r = 1.0 / np.sqrt(mass)
    eye = np.eye(2)
    imps = [] if impactor is None else [Impactor(rows=r * eye, housing_mass=mass, **impactor)]
    return LinearModel(M=eye, C=2 * zeta * wn * eye, K=wn * wn * eye, B=r * eye,
                       sensors=r * eye, impactors=imps)


def three_mode_model(impactors=()):
    """Three modes with distinct frequencies and generic shapes, mass-normalized."""
    omega = 2 * np.pi * np.array([7.0, 23.0, 61.0])
    return LinearModel(M=np.eye(3), C=np.zeros((3, 3)), K=np.diag(omega ** 2),
                       B=np.array([[0.3], [-0.2], [0.1]]),
                       sensors=np.array([[0.3, -0.2, 0.1], [0.25, 0.3, -0.15]]),
                       impactors=list(impactors))


def harmonic(n_inputs, amplitude, omega, input_index=0, phase=0.0):
    """A forcing with one harmonic term (N, rad/s)."""
    return Forcing(n_inputs, [Harmonic(input_index, amplitude, omega, phase)])
