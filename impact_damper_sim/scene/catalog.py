"""Finding scene files: the ready-made scenes, a scene name or path to its file, and the
validated scene of a file without building it.

A bare name (``'sdof'``) is looked up as ``<name>.yaml`` in :func:`scene_dirs` (the source
tree's ``config/scenes`` first, then the installed share directory); anything that looks like
a path is one. :func:`validated` reads, overrides and validates a file: the dict that the
model budget is checked on before anything is built, and that the CLI checks its options
with. Kept apart from :mod:`.build` because none of it needs the finite elements, the modal
basis or the integrators.
"""
from __future__ import annotations

import os
import re
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import impact_damper_sim

from .loading import apply_overrides, file_kind, load_yaml
from .schema import SceneError, validate
from .spec import SCHEMA

__all__ = ['available_scenes', 'resolve_scene', 'scene_dirs', 'validated']

_NAME_RE = re.compile(r'[A-Za-z0-9][A-Za-z0-9_.-]*')


# --- finding scene files ------------------------------------------------------------------

def scene_dirs() -> list[Path]:
    """Return the directories searched for scene names, in search order.

    The source tree's ``config/scenes`` first (editable installs, checkouts), then the
    installed ``share/impact_damper_sim/config/scenes`` found through the ament index when
    ROS is available.

    Returns
    -------
    list of pathlib.Path
        Existing directories, without duplicates.
    """
    dirs = [Path(impact_damper_sim.__file__).resolve().parents[1] / 'config' / 'scenes']
    try:
        from ament_index_python.packages import get_package_share_directory
        dirs.append(Path(get_package_share_directory('impact_damper_sim')) / 'config' / 'scenes')
    except Exception:   # no ROS, AMENT_PREFIX_PATH unset, or package not installed
        pass
    out: list[Path] = []
    for d in dirs:
        if d.is_dir() and d.resolve() not in [o.resolve() for o in out]:
            out.append(d)
    return out


def available_scenes() -> list[str]:
    """Return the names of the ready-made scenes (sorted list of str)."""
    return sorted({p.stem for d in scene_dirs() for p in d.glob('*.yaml')})


def _is_path(text: str | os.PathLike[str]) -> bool:
    return (isinstance(text, os.PathLike) or '/' in text or os.sep in text
            or text.endswith(('.yaml', '.yml')))


def resolve_scene(scene_name_or_path: str | os.PathLike[str]) -> Path:
    """Return the file of a scene given by name (``'sdof'``) or path.

    Parameters
    ----------
    scene_name_or_path : str or os.PathLike
        A bare name is looked up as ``<name>.yaml`` in :func:`scene_dirs`; anything with a
        directory separator or a ``.yaml``/``.yml`` suffix is a path.

    Returns
    -------
    pathlib.Path
        The scene file.

    Raises
    ------
    SceneError
        If the file does not exist or the name is unknown (the message lists the known ones).
    """
    if _is_path(scene_name_or_path):
        path = Path(scene_name_or_path)
        if not path.exists():
            raise SceneError(f'scene file {str(path)!r} does not exist')
        if not path.is_file():   # a directory, a FIFO, a device: never opened
            try:
                kind = file_kind(path)
            except OSError as exc:
                kind = exc.strerror
            raise SceneError(f'{str(path)!r} is not a scene file ({kind}, not a regular '
                             'file)')
        return path
    name = str(scene_name_or_path)
    if _NAME_RE.fullmatch(name):
        for d in scene_dirs():
            path = d / f'{name}.yaml'
            if path.is_file():
                return path
    known = ', '.join(available_scenes()) or 'none'
    searched = ', '.join(str(d) for d in scene_dirs()) or 'no scene directory found'
    raise SceneError(f'unknown scene {name!r}; ready-made scenes: {known} (searched {searched}); '
                     'or give a path to a .yaml file')


def validated(scene_name_or_path: str | os.PathLike[str],
              overrides: Iterable[str] = ()) -> tuple[dict[str, Any], Path]:
    """Read, override and validate a scene file without building it.

    Parameters
    ----------
    scene_name_or_path : str or os.PathLike
        Scene name or path to a YAML file.
    overrides : sequence of str, optional
        ``'dotted.key=value'`` overrides, checked like the file's keys.

    Returns
    -------
    scene : dict
        The validated scene (SI units).
    path : pathlib.Path
        The file it came from.

    Raises
    ------
    SceneError
        For any problem, each line naming the scene key.
    """
    path = resolve_scene(scene_name_or_path)
    raw = load_yaml(path)
    return validate(SCHEMA, apply_overrides(raw, list(overrides)), source=str(path)), path
