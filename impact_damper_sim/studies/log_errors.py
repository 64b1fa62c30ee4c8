"""A log that could not be created or written to its end: the errors, their one line, the
exit status.

``study record``, ``study dataset`` and the node's recorder say the same thing of the same
failure: which file, the error without Python's decoration, and what is on disk (whether
``study recover`` can keep it).
"""
from __future__ import annotations

import os

#: Exit status of ``study record`` and ``study dataset`` when a log was not written to its
#: end (a disk error while writing: ENOSPC, EIO, a read-only file system, the file or its
#: directory removed); 2 when it could not even be created (nothing written), as for bad input
EXIT_WRITE_FAILED = 4


class LogOpenError(OSError):
    """A log could not be created (missing or read-only directory, a directory as the path,
    another writer holding it): nothing was written. ``str()`` is one line naming the file."""

    def __init__(self, message, path=None, errno_=None):
        super().__init__(message)
        self.path, self.errno_ = path, errno_

    def __str__(self):
        return self.args[0]


class LogWriteError(OSError):
    """A log was not written to its end (a disk error, or the file lost while written).

    ``str()`` is one line: the file, the error and what is on disk (the messages that reached
    an unfinished file, and ``study recover`` to keep them; or that nothing is left).

    Attributes
    ----------
    path : str
        The log.
    reason : str
        The error, one line (``No space left on device``).
    result : ~impact_damper_sim.studies.record.RecordResult or None
        What the run did up to the error (``finished`` False, ``write_error`` this text).
    recoverable : bool
        An unfinished regular file with data is there: ``study recover`` can read it.
    """

    def __init__(self, message, path=None, reason=None, result=None, recoverable=False):
        super().__init__(message)
        self.path, self.reason, self.result = path, reason, result
        self.recoverable = recoverable

    def __str__(self):
        return self.args[0]


def error_reason(exc):
    """One line of an ``OSError`` without the ``[Errno N]`` prefix and the quoted path.

    Parameters
    ----------
    exc : BaseException
        The error (an ``OSError``'s ``strerror`` when its text is Python's default form).

    Returns
    -------
    str
    """
    text = str(exc).strip()
    if isinstance(exc, OSError) and exc.strerror and text.startswith('[Errno'):
        text = exc.strerror
    lines = text.splitlines()
    return '; '.join(line.strip() for line in lines) if lines else type(exc).__name__


def open_error(exc, path):
    """A :class:`LogOpenError` of an ``OSError`` from creating ``path`` (one line, naming it).

    Parameters
    ----------
    exc : OSError
        The writer's error (its own one-line text when it names the file).
    path : str or os.PathLike
        The log.

    Returns
    -------
    LogOpenError
    """
    path = os.fspath(path)
    reason = error_reason(exc)
    message = reason if path in reason else f'cannot create {path}: {reason}'
    return LogOpenError(message, path, getattr(exc, 'errno', None))


def check_definitions(out):
    """Refuse to record when the ROS message definitions cannot be found, before ``out`` is
    created (each topic's schema is read from the ament index; it was a traceback after an
    empty file was made).

    Parameters
    ----------
    out : str or os.PathLike
        The log that would be written, named in the message.

    Raises
    ------
    SceneError
        One line: nothing written, and the ``AMENT_PREFIX_PATH`` to set.
    """
    from ..recording.definitions import AmentIndexError, check_ament_index
    from ..scene.schema import SceneError
    try:
        check_ament_index()
    except AmentIndexError as exc:
        raise SceneError(f'cannot record to {os.fspath(out)} (nothing written): '
                         f'{error_reason(exc)}') from None


def write_failure(path, error, stats, complete=None):
    """Say in one line why a log is not finished and what of it is on disk.

    Parameters
    ----------
    path : str or os.PathLike
        The log.
    error : BaseException or None
        The writer's error (None: the file vanished without one).
    stats : dict
        The writer's ``stats()``: ``messages_written`` (messages accepted before the error)
        and ``file_bytes`` (bytes that reached the file).
    complete : int, optional
        Messages known to be in complete chunks in the file (messages); None when unknown
        (then "up to" the accepted ones).

    Returns
    -------
    tuple of (str, str, bool)
        The line, the reason alone, and whether ``study recover`` can read the file.
    """
    path = os.fspath(path)
    n, size = stats.get('messages_written', 0), stats.get('file_bytes', 0)
    if not os.path.exists(path):   # writes to a deleted file succeed: only now is it seen
        reason = 'the file no longer exists (deleted, or its directory removed, while it was '\
                 'written)'
        return (f'{path}: {reason}: nothing of it is on disk ({n:,} messages lost)', reason,
                False)
    reason = 'write failed: ' + (error_reason(error) if error is not None
                                 else 'the log was not finished')
    if size == 0:
        return f'{path}: {reason}; nothing reached the file', reason, False
    if not os.path.isfile(path):   # a device or a FIFO: nothing to read back
        return (f'{path}: {reason}; up to {n:,} messages were sent to it before the error',
                reason, False)
    unfinished = f'{path}: {reason}; the log is unfinished (no summary)'
    if complete == 0:
        return (f'{unfinished} and holds no complete chunk: the {n:,} messages written before '
                'the error are lost (nothing to recover)', reason, False)
    if complete is None:
        return (f'{unfinished}: up to {n:,} messages ({size / 1e6:.2f} MB) reached it before '
                f'the error; `study recover {path} OUT.mcap` keeps those in its complete '
                'chunks', reason, True)
    return (f'{unfinished}: {complete:,} message{"s" if complete != 1 else ""} in complete '
            f'chunks ({size / 1e6:.2f} MB in the file) reached it before the error; `study '
            f'recover {path} OUT.mcap` makes a finished copy of them', reason, True)


__all__ = ['EXIT_WRITE_FAILED', 'LogOpenError', 'LogWriteError', 'check_definitions',
           'error_reason', 'open_error', 'write_failure']
