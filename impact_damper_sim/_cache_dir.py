"""Where Numba caches the compiled kernels: a per-user directory, never the source tree.

Without ``NUMBA_CACHE_DIR`` Numba writes its cache into ``__pycache__`` beside each source
file, so a checkout's source tree would fill with compiled code (about 10 MB). The package
sets ``NUMBA_CACHE_DIR`` on import, before any of its modules imports Numba, to
:func:`default_cache_dir` unless the user set it. Numba keeps one subdirectory per source
directory (named by a hash of its absolute path) and checks each source file's modification
time and size, so several checkouts can share the directory.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path


def default_cache_dir():
    """The per-user cache directory of the compiled kernels.

    Returns
    -------
    Path
        ``$XDG_CACHE_HOME/impact_damper_sim/numba``, or ``~/.cache/impact_damper_sim/numba``
        when ``XDG_CACHE_HOME`` is unset, empty or relative (the XDG base directory
        specification ignores a relative path).
    """
    base = os.environ.get('XDG_CACHE_HOME', '')
    if not os.path.isabs(base):
        base = Path.home() / '.cache'
    return Path(base) / 'impact_damper_sim' / 'numba'


def use_user_cache():
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
