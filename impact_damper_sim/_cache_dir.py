"""The package's per-user cache directories, never the source tree.

Everything lives under :func:`cache_root`, ``$XDG_CACHE_HOME/impact_damper_sim`` (or
``~/.cache/impact_damper_sim``):

* ``numba/``: the compiled kernels. Without ``NUMBA_CACHE_DIR`` Numba writes its cache into
  ``__pycache__`` beside each source file, so a checkout's source tree would fill with
  compiled code (about 10 MB). The package sets ``NUMBA_CACHE_DIR`` on import, before any of
  its modules imports Numba, to :func:`default_cache_dir` unless the user set it. Numba keeps
  one subdirectory per source directory (named by a hash of its absolute path) and checks
  each source file's modification time and size, so several checkouts can share the
  directory.
* ``designs/``: the accelerometer's mounted-resonance designs
  (:mod:`impact_damper_sim.live.resonance_design`), a fit of about 0.3 s of CPU that every
  process building a channel would otherwise repeat. One small JSON file per design, keyed by
  its inputs, the design module's source text, numpy's version and the machine's
  architecture, so checkouts and versions can share it too. :data:`DESIGN_CACHE_ENV` moves
  it or switches it off.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

#: Environment variable for the resonance designs' cache (:func:`design_cache_dir`): a
#: directory to use instead of ``<cache root>/designs``, or one of :data:`DESIGN_CACHE_OFF`
#: to fit every design again in each process and write nothing.
DESIGN_CACHE_ENV = 'IMPACT_DAMPER_SIM_DESIGN_CACHE'
#: Values of :data:`DESIGN_CACHE_ENV` that switch the designs' cache off (any case).
DESIGN_CACHE_OFF = ('off', '0', 'false', 'no', 'none')


def cache_root() -> Path:
    """The package's per-user cache directory, the parent of every cache it keeps.

    Returns
    -------
    Path
        ``$XDG_CACHE_HOME/impact_damper_sim``, or ``~/.cache/impact_damper_sim`` when
        ``XDG_CACHE_HOME`` is unset, empty or relative (the XDG base directory
        specification ignores a relative path).
    """
    base = os.environ.get('XDG_CACHE_HOME', '')
    if not os.path.isabs(base):
        base = str(Path.home() / '.cache')
    return Path(base) / 'impact_damper_sim'


def default_cache_dir() -> Path:
    """The per-user cache directory of the compiled kernels.

    Returns
    -------
    Path
        ``numba`` under :func:`cache_root`.
    """
    return cache_root() / 'numba'


def design_cache_dir() -> Path | None:
    """The directory of the resonance designs' cache, or None when it is switched off.

    Returns
    -------
    Path or None
        ``$IMPACT_DAMPER_SIM_DESIGN_CACHE`` when set to a path (``~`` expanded, a relative
        path taken from the working directory); None when set to ``off``, ``0``, ``false``,
        ``no`` or ``none``; ``designs`` under :func:`cache_root` when unset or empty. The
        directory need not exist yet.
    """
    value = os.environ.get(DESIGN_CACHE_ENV, '').strip()
    if not value:
        return cache_root() / 'designs'
    if value.lower() in DESIGN_CACHE_OFF:
        return None
    return Path(os.path.abspath(os.path.expanduser(value)))


def use_user_cache() -> str:
    """Point ``NUMBA_CACHE_DIR`` at :func:`default_cache_dir` unless it is set already.

    Returns
    -------
    str
        The cache directory now in effect.
    """
    if not os.environ.get('NUMBA_CACHE_DIR'):
        os.environ['NUMBA_CACHE_DIR'] = str(default_cache_dir())
        config = sys.modules.get('numba.core.config')
        if config is not None:
            # Numba imported first (by the user): it read the environment without the
            # variable, and would locate the kernels' caches in the source tree
            config.reload_config()
    return os.environ['NUMBA_CACHE_DIR']
