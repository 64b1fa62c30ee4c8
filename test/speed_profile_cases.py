"""Speed profiles the bit-for-bit tests of the profile's fast paths run over (shared by
test_profile_paths.py and test_tach_fast.py)."""
import numpy as np

from impact_damper_sim.scene.excitation import (
    CommandedSpeed,
    ConstantSpeed,
    PaperRamp,
    PiecewiseLinearSpeed,
)


def speed_profiles(seed, signed_zero=False):
    """A ramp from rest, constant speeds (0 and, with ``signed_zero``, -0.0 too), four random
    multi-knot profiles (drawn with ``seed``, each with a knot at rest) and two commanded
    drives (hpotp's start-up; up, down to rest and up again)."""
    rng = np.random.default_rng(seed)
    yield PaperRamp(2400.0, 5.0)   # a ramp from rest: w = 0 on the first segment
    yield ConstantSpeed(300.0)
    yield ConstantSpeed(0.0)   # never turns: the keyphasor's angles are never reached
    if signed_zero:
        yield ConstantSpeed(-0.0)
    for i in range(4):
        n = 2 + i
        times = np.cumsum(rng.uniform(0.05, 1.5, n)) + (0.7 if i % 2 else -0.4)
        speeds = rng.uniform(0.0, 3000.0, n)
        speeds[i % n] = 0.0
        yield PiecewiseLinearSpeed(times, speeds)
    drive = CommandedSpeed(0.0, 480.0)   # hpotp's start-up
    drive.command(0.0, 2400.0)
    yield drive
    drive = CommandedSpeed(150.0, 900.0)   # up, down to rest, up again
    for t_now, target in ((0.3, 2000.0), (1.2, 0.0), (2.9, 800.0)):
        drive.command(t_now, target)
    yield drive
