"""Result files written whole or not at all, through whatever the target is: the one way every command writes.

A command checks its arguments and its output path first (:func:`check_writable`), then writes its result through
:func:`atomic_path` or :func:`atomic_open`, which look at what the target is:

* a regular file, or nothing yet: the data goes to a hidden temporary file in the target's folder
  (``.NAME.<pid>.tmp``, so the rename stays on one file system) that is renamed onto the target (``os.replace``,
  atomic on POSIX) only when the block ends without an exception, with the old file's permission mode (and, where
  allowed, its owner). An error, an interrupt or a kill before that leaves the previous result byte-identical,
  and no temporary file once the block has run (a killed process may leave one; readers ignore names starting
  with ``.``);
* a symbolic link: followed to the file it names, which is then written as above (the temporary file beside
  that file); the link stays a link;
* a device, a FIFO, a socket or any other special file (``-o /dev/null``, a named pipe a reader waits on): opened
  for writing and written in place, never renamed over, never unlinked.

:class:`Destination` is that decision for writers that cannot write inside one block (the MCAP recorder, which
renames its file into place at its first message).
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
from pathlib import Path

__all__ = ["atomic_path", "atomic_open", "temporary_beside", "check_writable", "Destination"]


def temporary_beside(target) -> Path:
    """The hidden temporary name of ``target`` in its own folder: ``DIR/.NAME.<pid>.tmp``."""
    target = Path(target)
    return target.with_name(f".{target.name}.{os.getpid()}.tmp")


def _resolved(target) -> Path:
    """``target`` with a symbolic link (or a chain of them) followed to the file it names (which may not exist
    yet); any other path as given."""
    target = Path(target)
    return Path(os.path.realpath(target)) if target.is_symlink() else target


class Destination:
    """Where a result for ``target`` is written and how it takes its place (see the module docstring).

    ``path`` is the file to open for writing: a temporary file beside the (resolved) target, or the target itself
    when it is a special file (``in_place``). :meth:`commit` puts a finished temporary file into place with the
    old file's mode; :meth:`discard` removes it. Both do nothing for a file written in place. A read-only
    regular file raises ``PermissionError`` (:func:`check_writable` has refused it before any work).
    """

    def __init__(self, target):
        self.target = Path(target)
        self.real = _resolved(self.target)
        try:
            st = os.stat(self.real)
        except OSError:  # not there yet (or not reachable: opening the temporary file says why)
            st = None
            if os.path.islink(self.real):  # the links go round in a circle: writing would fail, never replace one
                raise OSError(errno.ELOOP, os.strerror(errno.ELOOP), str(self.target)) from None
        #: a device, FIFO, socket (or folder: opening it fails, it is never replaced) is written in place
        self.in_place = st is not None and not stat.S_ISREG(st.st_mode)
        self._old = st if st is not None and stat.S_ISREG(st.st_mode) else None
        if self._old is not None and not (self._old.st_mode & 0o222 and os.access(self.real, os.W_OK)):
            # a read-only file is not replaced behind its owner's back (root included): as writing it would fail
            raise PermissionError(errno.EACCES, "the file is read-only", str(self.target))
        self.path = self.real if self.in_place else temporary_beside(self.real)
        self.committed = False

    def commit(self) -> None:
        """Rename the temporary file onto the target, with the mode (and owner, where allowed) of the file it
        replaces."""
        if self.in_place or self.committed:
            self.committed = True
            return
        if self._old is not None:
            if (self._old.st_uid, self._old.st_gid) != (os.geteuid(), os.getegid()):
                with contextlib.suppress(OSError):  # only root (or the owner, for the group) may
                    os.chown(self.path, self._old.st_uid, self._old.st_gid)
            os.chmod(self.path, stat.S_IMODE(self._old.st_mode))
        os.replace(self.path, self.real)
        self.committed = True

    def discard(self) -> None:
        """Remove the temporary file if it is there (never the target, never a file written in place)."""
        if self.in_place or self.committed:
            return
        with contextlib.suppress(OSError):
            if os.path.lexists(self.path):
                os.unlink(self.path)


@contextlib.contextmanager
def atomic_path(target, *, keep_on=()):
    """Yield the path to write ``target``'s new content to; put it in place when the block ends.

    For a regular file (or a new one, or a symlink's target) that is a temporary file beside it, renamed onto it
    when the block ends with the old file's mode; for a device, FIFO or other special file, the target itself,
    written in place. An exception in the block removes the temporary file and leaves ``target`` as it was,
    except one of the types in ``keep_on`` (e.g. ``IntegrationError``: the rows before a blow-up are a result
    too): then the file is renamed into place before the exception goes on.
    """
    dest = Destination(target)
    try:
        yield dest.path
    except BaseException as e:
        if keep_on and isinstance(e, keep_on) and os.path.exists(dest.path):
            dest.commit()
        raise
    else:
        dest.commit()
    finally:
        dest.discard()


@contextlib.contextmanager
def atomic_open(target, mode: str = "w", *, keep_on=(), **kwargs):
    """``open`` the file :func:`atomic_path` yields for ``target`` and put it in place when the block ends; the
    file is closed before the rename."""
    with atomic_path(target, keep_on=keep_on) as tmp:
        with open(tmp, mode, **kwargs) as fh:
            yield fh


def check_writable(target, flag: str) -> Path:
    """Refuse a result path whose folder is missing, not a folder or not writable, or that is itself a folder or a
    read-only file - before any work, so a bad path costs nothing. The error (a ``GyrosimError``, exit code 2)
    names ``flag``: ``--plot 'x/a.png' cannot be written: folder 'x' does not exist``. Returns it as a Path.

    A symlink is checked as the file it names (its folder gets the temporary file); a device, FIFO or other
    special file is written in place, so only the file itself must be writable. A regular file with no write
    permission bit (``chmod a-w``) is read-only for root too. An empty path (``-o ""``) names no file: refused."""
    from .errors import GyrosimError

    if isinstance(target, str) and not target.strip():  # Path("") is "." (the current folder): never a result
        raise GyrosimError(f"{flag} {target!r} cannot be written: an empty path names no file")
    target = Path(target)
    real = _resolved(target)
    folder = real.parent
    try:
        st = os.stat(real)
    except OSError:
        st = None
    reason = None
    if st is None and real.is_symlink():
        reason = "its symbolic links go round in a circle"
    elif real.is_dir():
        reason = "it is a folder"
    elif st is not None and not stat.S_ISREG(st.st_mode):  # written in place: the folder is not touched
        if not os.access(real, os.W_OK):
            reason = "the file is read-only"
    elif not folder.exists():
        reason = f"folder {str(folder)!r} does not exist"
    elif not folder.is_dir():
        reason = f"{str(folder)!r} is not a folder"
    elif not os.access(folder, os.W_OK | os.X_OK):
        reason = f"folder {str(folder)!r} is not writable"
    elif st is not None and (not os.access(real, os.W_OK) or not st.st_mode & 0o222):
        reason = "the file is read-only"
    if reason:
        raise GyrosimError(f"{flag} {str(target)!r} cannot be written: {reason}")
    return target
