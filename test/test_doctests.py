"""The doctest examples of the main public entry points run and pass (issue 37 item 4).

Each module below is run with :func:`doctest.testmod`; a failed example fails the test, and
so does a module with fewer examples than listed (a removed or skipped example is caught:
``attempted`` counts only examples that ran). The examples load a scene, run a simulation,
write and read a log, and show the beam element and the assembly; each module's take a few
seconds once the Numba cache is warm (the first simulation of a fresh cache compiles the
kernels: about a minute).
"""
import doctest
import importlib

import pytest

#: module -> least number of examples that must run (the count when they were written)
MODULES = {
    'impact_damper_sim': 12,                          # quick tour: load, simulate, impacts
    'impact_damper_sim.scene': 6,                     # schema, units, overrides, errors
    'impact_damper_sim.recording': 13,                # write an MCAP, read it back
    'impact_damper_sim.studies.log_reader': 12,       # study record's log of sdof, read
    'impact_damper_sim.fem.beam': 11,                 # 12 E I / L^3, k[:4, :4], lumped mass
    'impact_damper_sim.fem.assembly': 19,             # cantilever tip deflection
    'impact_damper_sim.fem.materials': 2,
    'impact_damper_sim.fem.sections': 2,
    'impact_damper_sim.modal.basis': 7,               # a two-mass modal reduction
}

FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


@pytest.mark.parametrize('name', sorted(MODULES))
def test_module_examples_pass(name):
    failed, attempted = doctest.testmod(importlib.import_module(name), optionflags=FLAGS,
                                        report=False)
    assert failed == 0, f'{name}: {failed} doctest examples failed (their output is above)'
    assert attempted >= MODULES[name], (
        f'{name}: {attempted} doctest examples ran, {MODULES[name]} expected: an example was '
        'removed or skipped (lower the count here only if that was meant)')
