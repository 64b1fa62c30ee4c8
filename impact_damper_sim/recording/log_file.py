"""The file under a log being written: opened by one writer only, errors in one line.

* :func:`open_log` creates (or, with ``overwrite``, reuses) the file and takes an exclusive
  ``flock`` on it before anything is truncated, so a second writer -- another node, ``study
  record``, ``study dataset``, or a second writer in this process -- is refused with
  :class:`FileLockedError` naming the holder, and never destroys the first one's data. The
  kernel drops the lock when its holder closes the file or dies (SIGKILL included): a crash
  never leaves a stale lock, and there is no lock file beside the log. Only regular files
  are locked and truncated (``/dev/full`` or a FIFO are written as they are).
* Every opening error is an ``OSError`` (of the usual subclass: ``FileNotFoundError``,
  ``PermissionError``, ...) whose ``str()`` is one line naming the file and the reason,
  e.g. ``cannot create /ro/x.mcap: Read-only file system``.
* :func:`vanished` tells whether the file was deleted or moved while written (the writes
  all succeed then, so only the writer can tell).

The holder is found in ``/proc/locks`` (Linux): ``process 1234 (vibration_node --ros-args
...)``; where that is not readable, ``another process``.
"""
from __future__ import annotations

import errno
import fcntl
import os
import stat

#: Longest command line (characters) quoted in a refusal.
_COMMAND_CHARS = 80


class OneLineError:
    """Mixin of every ``OSError`` raised here: its text is its message alone (not ``[Errno 2]
    ...: 'path'``), one line naming the file, so that a caller can show ``str(exc)``."""

    def __str__(self):
        return self.strerror

    def __reduce__(self):   # keep errno, message and file across processes (pickle)
        return type(self), (self.errno, self.strerror, self.filename)


class LogFileError(OneLineError, OSError):
    """A log file cannot be opened for writing, or was lost while written (one-line text)."""


class FileLockedError(OneLineError, OSError):
    """Another writer (this process or another) is writing the file; ``errno`` EBUSY."""


class _FileExistsError(OneLineError, FileExistsError):
    """The file exists and ``overwrite`` is false."""


class _FileNotFoundError(OneLineError, FileNotFoundError):
    pass


class _PermissionError(OneLineError, PermissionError):
    pass


class _IsADirectoryError(OneLineError, IsADirectoryError):
    pass


class _NotADirectoryError(OneLineError, NotADirectoryError):
    pass


_CLASSES = {errno.EEXIST: _FileExistsError, errno.ENOENT: _FileNotFoundError,
            errno.EACCES: _PermissionError, errno.EPERM: _PermissionError,
            errno.EISDIR: _IsADirectoryError, errno.ENOTDIR: _NotADirectoryError}


def log_error(code, message, path):
    """Return a one-line ``OSError`` of the subclass ``code`` calls for.

    Parameters
    ----------
    code : int
        ``errno`` value.
    message : str
        The whole text, naming the file.
    path : str
        The file.

    Returns
    -------
    OSError
    """
    return _CLASSES.get(code, LogFileError)(code, message, path)


def _cannot_create(path, exc):
    code = exc.errno if exc.errno is not None else errno.EIO
    reason = exc.strerror or os.strerror(code)
    if code == errno.ENOENT:
        parent = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(parent):
            reason += f' (directory {parent} does not exist)'
    return log_error(code, f'cannot create {path}: {reason}', path)


def open_log(path, overwrite, overwrite_option):
    """Open ``path`` for writing, locked for this writer alone; return the file descriptor.

    Without ``overwrite`` the file must not exist (``O_EXCL``: no race with another
    creator). With it, an existing file is opened without ``O_TRUNC``, locked, and only then
    truncated, so a file another writer holds is left untouched.

    Parameters
    ----------
    path : str
        The log file.
    overwrite : bool
        Replace an existing file.
    overwrite_option : str
        What the user sets for ``overwrite``, named when the file exists.

    Returns
    -------
    int
        File descriptor (write-only, close-on-exec), locked with ``LOCK_EX`` when the file is
        a regular file.

    Raises
    ------
    FileLockedError
        Another writer holds the file.
    FileExistsError
        The file exists and ``overwrite`` is false.
    OSError
        The file cannot be created (one-line text; ``FileNotFoundError``, ``PermissionError``,
        ``IsADirectoryError`` ... as the cause is).
    """
    flags = os.O_WRONLY | os.O_CREAT | getattr(os, 'O_CLOEXEC', 0)
    if not overwrite:
        flags |= os.O_EXCL
    try:
        fd = os.open(path, flags, 0o644)
    except FileExistsError:
        if os.path.isdir(path):
            raise log_error(errno.EISDIR, f'cannot create {path}: '
                            f'{os.strerror(errno.EISDIR)}', path) from None
        holder = holder_of(path)
        if holder is not None:
            raise _locked(path, holder) from None
        raise _FileExistsError(errno.EEXIST, f'{path} exists; not overwriting it (set '
                               f'{overwrite_option} to replace it)', path) from None
    except OSError as exc:
        raise _cannot_create(path, exc) from None
    try:
        if stat.S_ISREG(os.fstat(fd).st_mode):
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise _locked(path, lock_holder(os.fstat(fd))) from None
            if overwrite:
                os.ftruncate(fd, 0)
    except FileLockedError:
        os.close(fd)
        raise
    except OSError as exc:
        os.close(fd)
        raise _cannot_create(path, exc) from None
    return fd


def close_log(fd):
    """Unlock (for every process sharing the descriptor, e.g. after a fork) and close.

    Parameters
    ----------
    fd : int
        From :func:`open_log`.

    Raises
    ------
    OSError
        From ``close`` (e.g. a delayed write error of a network file system).
    """
    try:
        fcntl.flock(fd, fcntl.LOCK_UN)
    except OSError:   # not lockable (a device): nothing to release
        pass
    os.close(fd)


def _locked(path, holder):
    return FileLockedError(errno.EBUSY, f'{path} is being written by {holder}; not writing '
                           f'it', path)


def holder_of(path):
    """The writer holding an existing regular file (``process 1234 (command line)``), or None
    if it is not locked, not a regular file or does not exist.

    Parameters
    ----------
    path : str or os.PathLike
        A log file.

    Returns
    -------
    str or None
    """
    try:
        if not stat.S_ISREG(os.stat(path).st_mode):
            return None
        fd = os.open(path, os.O_RDONLY | getattr(os, 'O_CLOEXEC', 0) | os.O_NONBLOCK)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)   # fails only under an exclusive lock
        return None
    except BlockingIOError:
        return lock_holder(os.fstat(fd))
    except OSError:
        return None
    finally:
        os.close(fd)   # releases the shared lock if we got it


def lock_holder(st):
    """Describe the process holding an exclusive ``flock`` on a file, for a message.

    Parameters
    ----------
    st : os.stat_result
        The file's status (device and inode).

    Returns
    -------
    str
        ``process 1234 (command line)``, ``process 1234 (this process, command line)``, or
        ``another process`` where ``/proc/locks`` does not tell.
    """
    key = f'{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}'
    pid = None
    try:
        with open('/proc/locks', encoding='ascii', errors='replace') as f:
            for line in f:
                # '1: FLOCK  ADVISORY  WRITE 1234 fe:00:2146721 0 EOF' ('1: -> ...' waits)
                fields = line.split()
                if len(fields) >= 6 and fields[1] == 'FLOCK' and fields[3] == 'WRITE' \
                        and fields[5] == key:
                    pid = int(fields[4])
                    break
    except (OSError, ValueError):
        pass
    if not pid:   # not found, or 0: the holder is outside this pid namespace
        return 'another process'
    command = _command_line(pid)
    if pid == os.getpid():
        command = f'this process{", " + command if command else ""}'
    return f'process {pid} ({command})' if command else f'process {pid}'


def _command_line(pid):
    try:
        with open(f'/proc/{pid}/cmdline', 'rb') as f:
            argv = f.read(4096).split(b'\0')
    except OSError:
        return ''
    argv = [a.decode('utf-8', 'replace') for a in argv if a]
    if not argv:
        return ''
    text = ' '.join(' '.join([os.path.basename(argv[0])] + argv[1:]).split())   # one line
    return text if len(text) <= _COMMAND_CHARS else text[:_COMMAND_CHARS - 3] + '...'


def vanished(fd, path, st, absolute=None, check_moved=True):
    """Return a one-line ``OSError`` if the file was deleted or moved while written, else None.

    Parameters
    ----------
    fd : int
        The open log.
    path : str
        Its name as the caller gave it (for the message).
    st : os.stat_result
        Its status when it was opened (device and inode).
    absolute : str, optional
        ``path`` made absolute when it was opened (so a later ``chdir`` is no move);
        default ``path``.
    check_moved : bool, optional
        Also check that ``path`` still names the file (at close; while writing, a moved
        file still takes the data, a deleted one keeps nothing).

    Returns
    -------
    OSError or None
        ``ENOENT``: ``<path> was deleted while being written ...`` (no name is left: the
        data goes when the file is closed) or ``<path> was moved while being written ...``
        (the path is gone or names another file; where the file is now, when known).
    """
    try:
        now = os.fstat(fd)
    except OSError:
        return None
    if not stat.S_ISREG(now.st_mode):
        return None
    if now.st_nlink == 0:
        return log_error(errno.ENOENT, f'{path} was deleted while being written (with its '
                         'directory, or on its own); what was recorded is lost', path)
    if not check_moved:
        return None
    try:
        there = os.stat(absolute or path)
        moved = (there.st_dev, there.st_ino) != (st.st_dev, st.st_ino)
    except OSError:
        moved = True
    if not moved:
        return None
    try:
        where = f'the file is now {os.readlink(f"/proc/self/fd/{fd}")}'
    except OSError:
        where = 'the name now names another file or none'
    return log_error(errno.ENOENT, f'{path} was moved while being written ({where}); the '
                     'log is not at that path', path)
