"""One policy for every command's output paths (docs/cli.md, "Output paths"), checked before any work:

- **an output file** (``simulate -o``, ``--show-plot``'s PNG, ``chaos --plot``, ``linearize -o/--plot``,
  ``cosim SYSTEM.ssp --build`` and ``--plot``, ``serve --record``, ``record -o``, ``mcap recover OUT``): its folder
  must exist; a missing folder, a folder that is not writable, a target that is a folder or a read-only file is
  refused (:func:`gyrosim._atomic.check_writable`);
- **an output folder** (``fmu build --output``, ``sweep --output``, ``sweep-plot --output-dir``, ``plot
  --output-dir``, ``bench --output``): an existing folder, or a new one whose parent folder exists (made by the
  command); a missing parent, a file in its place or a parent that is not writable is refused. A command's default
  folder (``fmu build``'s ``fmu/dist``, ``bench``'s ``docs/study``) is made with its parents.

Every refusal is one line naming the flag, the path and the reason (a :class:`~gyrosim.errors.GyrosimError`, exit
code 2: a usage error), and nothing has been created or touched.
"""

from __future__ import annotations

import os
from pathlib import Path

from ._atomic import check_writable
from .errors import GyrosimError

__all__ = ["output_file", "output_folder"]


def output_file(target, flag: str) -> Path:
    """Check an output file's path (its folder must exist and be writable; see the module's notes)."""
    return check_writable(target, flag)


def output_folder(target, flag: str, *, default: bool = False, make: bool = False) -> Path:
    """Check an output folder's path: an existing writable folder, or a new one whose parent folder exists and is
    writable (``default``: a command's default folder, whose parents may be missing too). With ``make``, make it
    (and, for a default, its parents). Returns it as a Path.

    Raises
    ------
    GyrosimError
        ``--output 'x/y' cannot be used: folder 'x' does not exist (an output folder is made only inside an
        existing one)``, and the like; exit code 2.
    """
    if isinstance(target, str) and not target.strip():  # Path("") is "." (the current folder): never meant
        raise GyrosimError(f"{flag} {target!r} cannot be used: an empty path names no folder")
    target = Path(target)
    reason = None
    if target.exists():
        if not target.is_dir():
            reason = "it is a file, not a folder"
        elif not os.access(target, os.W_OK | os.X_OK):
            reason = "the folder is not writable"
    else:
        parent = target.parent
        if not default:
            if not parent.exists():
                reason = (f"folder {str(parent)!r} does not exist (an output folder is made only inside an existing "
                          "one)")
            elif not parent.is_dir():
                reason = f"{str(parent)!r} is not a folder"
            elif not os.access(parent, os.W_OK | os.X_OK):
                reason = f"folder {str(parent)!r} is not writable"
        else:  # the first existing folder above it must be a writable folder
            up = parent
            while not up.exists() and up != up.parent:
                up = up.parent
            if not up.is_dir():
                reason = f"{str(up)!r} is not a folder"
            elif not os.access(up, os.W_OK | os.X_OK):
                reason = f"folder {str(up)!r} is not writable"
    if reason:
        raise GyrosimError(f"{flag} {str(target)!r} cannot be used: {reason}")
    if make:
        try:
            target.mkdir(parents=default, exist_ok=True)
        except OSError as e:
            raise GyrosimError(f"{flag} {str(target)!r} cannot be made: {e.strerror or e}") from None
    return target
