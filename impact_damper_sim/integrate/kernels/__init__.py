"""All Numba kernels of the project, one module per integrator.

Conventions: float64/complex128 arrays only, no Python objects, state arrays updated in
place, times in s. Each kernel ``name`` is compiled with ``numba.njit(cache=True)`` from a
plain Python/NumPy function ``name_py`` kept beside it: that twin is what the tests compare
the compiled kernel against (``test/test_kernels*.py``), so the JIT never hides an untested
path. Set ``NUMBA_CACHE_DIR`` to choose where compiled kernels are cached.
"""
