"""The tick period of a recorded run (s of sim time per stepped chunk): checked and read.

``study record --tick-period``, a data set's ``tick_period`` and the node's ``tick_period``
take the same range, :data:`~impact_damper_sim.recording.node_topics.TICK_PERIOD_RANGE`.
"""
from __future__ import annotations

from ..recording.node_topics import TICK_PERIOD_RANGE


def tick_period_range_text():
    """The allowed tick_period, as error messages give it: ``[0.001, 0.1] s``."""
    low, high = TICK_PERIOD_RANGE
    return f'[{low:g}, {high:g}] s'


def check_tick_period(value, name='tick_period', shown=None):
    """Return ``value`` (s) as a float if it is a tick_period the node takes.

    Parameters
    ----------
    value : float
        Sim time per stepped chunk (s).
    name : str
        What the caller calls it (``tick_period``, ``--tick-period``), named in the error.
    shown : str, optional
        The value as the user wrote it (``'500 ms'``), for the error; default ``value`` in s.

    Raises
    ------
    SceneError
        ``value`` is not a number in :data:`TICK_PERIOD_RANGE` (closed); the message names
        ``name`` and the range.
    """
    from ..scene.schema import SceneError
    low, high = TICK_PERIOD_RANGE
    number = None
    if not isinstance(value, bool):
        try:
            number = float(value)
        except (TypeError, ValueError):
            pass
    if number is None or not low <= number <= high:   # NaN is outside too
        if shown is None:
            shown = f'{number:g} s' if number is not None else repr(value)
        raise SceneError(f'{name}: {shown} is out of range {tick_period_range_text()}')
    return number


def parse_tick_period(text, name='tick_period'):
    """Read a tick_period as a user writes it (s, or a time with its unit: ``'100 ms'``).

    Parameters
    ----------
    text : str or float
        The value as given (s when a bare number).
    name : str
        The option or key it came from, named in the error.

    Returns
    -------
    float
        The tick period (s), in :data:`TICK_PERIOD_RANGE`.

    Raises
    ------
    SceneError
        Not a time, or out of range: one line naming ``name``, the value and the range.
    """
    from ..scene.schema import SceneError
    from ..scene.units import UnitError, parse_quantity
    try:
        seconds = parse_quantity(text, 'time', key=name)
    except UnitError as exc:
        reason = str(exc).removeprefix(f"'{name}': ")
        raise SceneError(f'{name}: {reason}; expected a time in '
                         f'{tick_period_range_text()}') from None
    return check_tick_period(seconds, name, shown=str(text))


__all__ = ['check_tick_period', 'parse_tick_period', 'tick_period_range_text']
