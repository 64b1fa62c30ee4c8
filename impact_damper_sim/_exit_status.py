"""Exit statuses the package's commands share (``study``, ``study recover``, the replay tool).

Defined once here, so that the engine (a diverged run), the studies and the command lines
agree on them; constants only, importing nothing, so it sits outside the layers as
``_cache_dir`` does.
"""
from __future__ import annotations

#: A usage or input error (one line on stderr), as argparse exits.
EXIT_USAGE = 2
#: A run diverged (:class:`impact_damper_sim.integrate.divergence.Divergence`).
EXIT_DIVERGED = 3

__all__ = ['EXIT_DIVERGED', 'EXIT_USAGE']
