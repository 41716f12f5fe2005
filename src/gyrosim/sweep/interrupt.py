"""Ctrl-C during a sweep: noted when it comes, acted on in the sweep's own code (exit 130, the chunks kept).

Python's own SIGINT handler raises ``KeyboardInterrupt`` in whatever the main thread runs at that moment, and two
such moments lose it or misreport it:

* in a finalizer or a weakref callback (importlib's module locks while a module is imported, a Dask future's
  ``__del__``), the exception is printed as "Exception ignored in ..." and dropped: the sweep runs on to its end
  and exits 0;
* in code run by ``exec`` or ``eval`` (the methods ``dataclasses`` and ``namedtuple`` make while a module is
  imported), CPython remembers the interrupt as unhandled even though ``gyrosim sweep`` catches it, prints its
  message and returns 130: the process then kills itself with SIGINT at exit instead of exiting 130.

So while a sweep runs, :class:`deferred` puts in a handler that only notes the interrupt, and the sweep calls
:func:`check` after every engine call, before every chunk and every 0.05 s while it waits for a Dask result;
``KeyboardInterrupt`` is raised there. That is as soon as before: Python's handler, too, runs only once the
engine call under way has returned. A second Ctrl-C before the first was acted on raises at once (Python's old
behaviour), a way out should the sweep be stuck where it does not check.

The handler is put in only in the main thread and only over Python's default one: a SIGINT the parent process set
to be ignored stays ignored (a job that a script starts with ``&`` inherits SIGINT ignored; Python keeps that,
and so does the sweep), and a program that installed its own handler keeps it.
"""

from __future__ import annotations

import signal
import threading

__all__ = ["deferred", "check", "noted"]

_noted = False


def _note(signum, frame) -> None:
    global _noted
    if _noted:  # the second Ctrl-C: at once
        raise KeyboardInterrupt
    _noted = True


def noted() -> bool:
    """Whether an interrupt came that the sweep has not yet acted on (in the main thread; False elsewhere)."""
    return _noted and threading.current_thread() is threading.main_thread()


def check() -> None:
    """Raise ``KeyboardInterrupt`` if an interrupt was noted (only in the main thread: a chunk running in a
    worker thread of an in-process Dask cluster is left to the main thread's check)."""
    if noted():
        raise KeyboardInterrupt


class deferred:
    """``with deferred():`` SIGINT only noted in the block (see the module docstring); on leaving it, Python's
    handler is back and a noted interrupt is raised as ``KeyboardInterrupt`` (unless another exception is on its
    way). Nested blocks share the outer one's handler."""

    def __enter__(self) -> deferred:
        global _noted
        self._old = None
        if (threading.current_thread() is threading.main_thread()
                and signal.getsignal(signal.SIGINT) is signal.default_int_handler):
            _noted = False
            self._old = signal.signal(signal.SIGINT, _note)
        return self

    def __exit__(self, typ, exc, tb) -> bool:
        global _noted
        if self._old is None:  # nested, not the main thread, or SIGINT not Python's to handle
            if typ is None:
                check()
            return False
        signal.signal(signal.SIGINT, self._old)
        was, _noted = _noted, False
        if was and typ is None:
            raise KeyboardInterrupt
        return False
