"""Parameter studies: frequency responses, grid sweeps and stability maps (paper section 4),
and the speed/accuracy trade of the integrators (:mod:`.convergence`).

Each study turns its arguments into independent points (a scene, ``--set`` overrides and run
settings) and runs them through :func:`.runner.run_points` on a ``concurrent.futures``
executor: local processes (default), serial, or a Dask cluster. Importing this package is
cheap; NumPy and the simulator are imported by the point tasks.
"""
