"""What every study command prints and how it ends: exit codes, errors, JSON, numbers, tables.

The one module the command line (:mod:`impact_damper_sim.cli`) and the studies
(:mod:`impact_damper_sim.studies`) both use for their output; it imports neither, so imports
run one way: ``cli`` -> ``studies`` -> here.
"""
from __future__ import annotations

import json
import math
import os
import sys

#: Default document of ``study validate --quick`` (the full one is docs/validation.md).
QUICK_VALIDATION_OUT = 'validation-quick.md'


class OutputExists(Exception):
    """An output file exists and ``--overwrite`` was not given (exit 2)."""


def refuse_existing(paths, overwrite):
    """Refuse, before any work, to replace existing output files without ``--overwrite``.

    Parameters
    ----------
    paths : iterable of str or None
        Output paths (None: not requested).
    overwrite : bool
        ``--overwrite`` was given.

    Raises
    ------
    OutputExists
        Naming the existing files; or, ``--overwrite`` or not, a log another writer is
        writing now, naming that writer (``--overwrite`` would not help).
    """
    from ..recording.log_file import holder_of
    existing = [p for p in paths if p and os.path.exists(p)]
    for path in existing:
        holder = holder_of(path)
        if holder is not None:
            raise OutputExists(f'{path} is being written by {holder}; not writing it')
    if existing and not overwrite:
        raise OutputExists(f"{', '.join(existing)} exist{'s' if len(existing) == 1 else ''}; "
                           'pass --overwrite to replace '
                           f"{'it' if len(existing) == 1 else 'them'}")


def print_error(message):
    """Print ``study: error: <first line>`` on stderr, further lines indented."""
    lines = message.splitlines() or ['']
    print('\n'.join([f'study: error: {lines[0]}'] + [f'  {line}' for line in lines[1:]]),
          file=sys.stderr)


def print_json(data):
    """Print ``data`` as strict JSON (non-finite floats as null), indented."""
    print(json.dumps(strict_json(data), indent=2))


def strict_json(value):
    """``value`` with non-finite floats replaced by None, so that the output is strict JSON."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: strict_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [strict_json(v) for v in value]
    return value


def fmt(x, digits=6):
    """``x`` with ``digits`` significant digits (``%g``), or ``n/a`` for None."""
    return 'n/a' if x is None else f'{x:.{digits}g}'


def table(header, rows):
    """Left-aligned text columns: the header row, then ``rows`` (cells made str)."""
    cells = [header] + [[str(c) for c in row] for row in rows]
    widths = [max(len(r[k]) for r in cells) for k in range(len(header))]
    return '\n'.join('  '.join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in cells)


__all__ = ['OutputExists', 'QUICK_VALIDATION_OUT', 'fmt', 'print_error', 'print_json',
           'refuse_existing', 'strict_json', 'table']
