"""Result files written whole or not at all: a temporary file beside the target, renamed into place.

A command checks its arguments first, then writes its result through :func:`atomic_path` or :func:`atomic_open`:
the data goes to a hidden temporary file in the target's folder (``.NAME.<pid>.tmp``, so the rename stays on one
file system) and is renamed onto the target (``os.replace``, atomic on POSIX) only when the block ends without an
exception. An error, an interrupt or a kill before that leaves the previous result byte-identical, and no
temporary file once the block has run (a killed process may leave one; readers ignore names starting with ``.``).
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

__all__ = ["atomic_path", "atomic_open", "temporary_beside", "check_writable"]


def temporary_beside(target) -> Path:
    """The hidden temporary name of ``target`` in its own folder: ``DIR/.NAME.<pid>.tmp``."""
    target = Path(target)
    return target.with_name(f".{target.name}.{os.getpid()}.tmp")


@contextlib.contextmanager
def atomic_path(target, *, keep_on=()):
    """Yield a temporary path beside ``target``; rename it onto ``target`` when the block ends.

    An exception in the block removes the temporary file and leaves ``target`` as it was, except one of the types
    in ``keep_on`` (e.g. ``IntegrationError``: the rows before a blow-up are a result too): then the file is
    renamed into place before the exception goes on.
    """
    target = Path(target)
    tmp = temporary_beside(target)
    try:
        yield tmp
    except BaseException as e:
        if keep_on and isinstance(e, keep_on) and tmp.exists():
            os.replace(tmp, target)
        raise
    else:
        os.replace(tmp, target)
    finally:
        with contextlib.suppress(OSError):
            if tmp.exists():
                tmp.unlink()


@contextlib.contextmanager
def atomic_open(target, mode: str = "w", *, keep_on=(), **kwargs):
    """``open`` a temporary file beside ``target`` and rename it into place when the block ends (see
    :func:`atomic_path`); the file is closed before the rename."""
    with atomic_path(target, keep_on=keep_on) as tmp:
        with open(tmp, mode, **kwargs) as fh:
            yield fh


def check_writable(target, flag: str) -> Path:
    """Refuse a result path whose folder is missing, not a folder or not writable, or that is itself a folder or a
    read-only file - before any work, so a bad path costs nothing. The error (a ``GyrosimError``, exit code 2)
    names ``flag``: ``--plot 'x/a.png' cannot be written: folder 'x' does not exist``. Returns it as a Path."""
    from .errors import GyrosimError

    target = Path(target)
    folder = target.parent
    reason = None
    if target.is_dir():
        reason = "it is a folder"
    elif not folder.exists():
        reason = f"folder {str(folder)!r} does not exist"
    elif not folder.is_dir():
        reason = f"{str(folder)!r} is not a folder"
    elif not os.access(folder, os.W_OK | os.X_OK):
        reason = f"folder {str(folder)!r} is not writable"
    elif target.exists() and not os.access(target, os.W_OK):
        reason = "the file is read-only"
    if reason:
        raise GyrosimError(f"{flag} {str(target)!r} cannot be written: {reason}")
    return target
