"""Ctrl-C and SIGTERM: every run ends at once, workers included, and leaves nothing behind (issue 49).

The one home of dampnet's signal handling:
  Terminated                SIGTERM as an exception. It is a KeyboardInterrupt, so every clean-up
                            written for Ctrl-C (a sweep saving its state, restarts stopping their
                            workers, atomic writers removing their temporary files) runs for it too.
  terminate_as_exception()  the command line's SIGTERM handler (dampnet.cli.main installs it, and
                            default_handlers() when it returns), and its hook for a KeyboardInterrupt
                            or Terminated that Python would print and drop (raised inside a weakref
                            callback or a finaliser, e.g. importlib's module-lock clean-up): the
                            signal is sent again, to be raised once that context has returned.
  Deferred                  around a section that must not be cut between two bytecodes (a process
                            pool's queues and locks): SIGINT and SIGTERM only set a flag, the section
                            polls `pending` and stops its workers itself, and on leaving the section
                            the signal is delivered again to the handler that was there before.
  children_ignore_interrupt()
                            around starting worker processes: SIGINT is ignored meanwhile, so the
                            new processes start ignoring it (a disposition SIG_IGN survives fork
                            and exec) and a Ctrl-C in the terminal, which reaches the whole
                            process group, cannot kill one while it imports.
  worker_ignores_interrupt()
                            a worker's first call: it ignores SIGINT for good (the parent decides
                            what Ctrl-C means and stops it), so Ctrl-C prints no traceback per
                            worker.
Why not let KeyboardInterrupt fly inside concurrent.futures: raised between two bytecodes of the
pool's own code it can leave a lock held or a queue half-written, and the parent then waited for
ever in shutdown (2 runs in 5 of the issue's probe).
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from contextlib import contextmanager
from typing import Iterator

#: the exit status of a run ended by SIGTERM (128 + the signal's number, as a shell reports it)
TERMINATED_STATUS = 128 + signal.SIGTERM
#: the exit status of a run ended by Ctrl-C
INTERRUPTED_STATUS = 128 + signal.SIGINT


class Terminated(KeyboardInterrupt):
    """The process was sent SIGTERM (a KeyboardInterrupt, so Ctrl-C's clean-up runs for it too)."""


def _raise_terminated(signum, frame) -> None:
    raise Terminated(f"signal {signum}")


def _redeliver_swallowed(previous):
    """sys.unraisablehook: a KeyboardInterrupt (Ctrl-C) or Terminated (SIGTERM) raised where Python
    can only print and drop it (a weakref callback, a __del__: the signal handler runs at whatever
    bytecode comes next, and importlib's module-lock clean-up is one such callback) sends its signal
    again, so that it is raised once that context has returned and the run still ends at once; any
    other unraisable exception goes to `previous`."""
    def hook(unraisable) -> None:
        exc = unraisable.exc_value
        if not isinstance(exc, KeyboardInterrupt):
            previous(unraisable)
            return
        # from another thread, a millisecond later: sent from here, it would be handled (and raised)
        # inside this hook, which drops it too; a main thread still inside the callback then comes
        # back here, once more, until the signal lands outside it
        signum = signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT
        for _ in range(3):
            try:
                again = threading.Timer(0.001, os.kill, (os.getpid(), signum))
                again.daemon = True
                again.start()
                return
            except KeyboardInterrupt:  # (it landed here already, on a loaded machine: once more)
                continue
            except RuntimeError:  # (the interpreter is shutting down: no new threads, nothing left to stop)
                return
    hook.redelivers = True
    return hook


def terminate_as_exception() -> None:
    """SIGTERM raises Terminated in the main thread (from then on), unless SIGTERM is ignored; a
    KeyboardInterrupt or Terminated that Python would drop is delivered again (_redeliver_swallowed)."""
    if threading.current_thread() is threading.main_thread():
        if signal.getsignal(signal.SIGTERM) is not signal.SIG_IGN:
            signal.signal(signal.SIGTERM, _raise_terminated)
        if not getattr(sys.unraisablehook, "redelivers", False):
            sys.unraisablehook = _redeliver_swallowed(sys.unraisablehook)


def default_handlers() -> None:
    """SIGINT and SIGTERM end the process at once from now on (the command line's last step: while
    the interpreter shuts down, a KeyboardInterrupt would only print a traceback)."""
    if threading.current_thread() is threading.main_thread():
        for s in (signal.SIGINT, signal.SIGTERM):
            if signal.getsignal(s) is not signal.SIG_IGN:
                signal.signal(s, signal.SIG_DFL)


class Deferred:
    """SIGINT and SIGTERM held as a flag while the `with` block runs (main thread only; elsewhere,
    and for a signal that was ignored, nothing changes). `pending` is the number of the first
    signal that came, or 0. On leaving, the old handlers come back and a held signal is delivered
    to them: KeyboardInterrupt or Terminated is raised then, or the process ends by the signal's
    default action. An exception the block raised because of the signal (`Stop`) is replaced by
    that; a handler that returns leaves RuntimeError."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    class Stop(Exception):
        """Raised by the block (`check()`) to leave at once when a signal is pending."""

    def __init__(self) -> None:
        self.pending = 0
        self._old: dict[int, object] = {}

    def _hold(self, signum, frame) -> None:
        if not self.pending:
            self.pending = signum

    def check(self) -> None:
        """Stop when a signal is pending."""
        if self.pending:
            raise Deferred.Stop(f"signal {self.pending}")

    def __enter__(self) -> "Deferred":
        if threading.current_thread() is threading.main_thread():
            for s in self.SIGNALS:
                old = signal.getsignal(s)
                if old is not signal.SIG_IGN and old is not None:
                    self._old[s] = old
                    signal.signal(s, self._hold)
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        for s, old in self._old.items():
            signal.signal(s, old)
        if not self.pending:
            return False
        if exc_type is not None and not issubclass(exc_type, Deferred.Stop):
            return False        # an error of its own came first: it is the one to report
        signal.raise_signal(self.pending)   # the old handler raises here, or the process ends
        raise RuntimeError(f"stopped by signal {self.pending}")


@contextmanager
def children_ignore_interrupt() -> Iterator[None]:
    """Processes that multiprocessing's spawn starts inside start with SIGINT ignored: an ignored
    signal stays ignored across fork and exec, and Python then installs no KeyboardInterrupt
    handler, so a Ctrl-C cannot kill a worker while it imports (its traceback printed) before
    worker_ignores_interrupt runs. SIGINT is ignored in this process only while each fork and exec
    runs (multiprocessing.util.spawnv_passfds, which waits for the exec: milliseconds), not while the
    pool is set up: a Ctrl-C in that time is dropped here too (measured: with the whole first
    submit inside, 1 of 20 signalled runs lost its Ctrl-C). Why not block it instead: spawn clears
    the new process's signal mask (measured on Python 3.11)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    import multiprocessing.util as mp_util

    spawn = mp_util.spawnv_passfds

    def spawn_ignoring_interrupt(*args, **kwargs):
        old = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            return spawn(*args, **kwargs)
        finally:
            signal.signal(signal.SIGINT, old)

    mp_util.spawnv_passfds = spawn_ignoring_interrupt
    try:
        yield
    finally:
        mp_util.spawnv_passfds = spawn


def worker_ignores_interrupt() -> None:
    """A worker process ignores SIGINT from now on."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
