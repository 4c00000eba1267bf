"""SIGINT, SIGTERM and SIGHUP as one way of stopping a run: each raises Signalled (a KeyboardInterrupt) between
steps, so a headless run closes its files in order whichever one a person, `timeout`, a job scheduler or a closing
terminal sends. While a frame's outputs are written (`held()`), a signal waits until they are whole."""

from __future__ import annotations

import signal
import sys
import threading
from contextlib import contextmanager

HANDLED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class Signalled(KeyboardInterrupt):
    """The run was asked to stop by signal `signum`; a process that stops for it exits 128 + signum."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


class Stopper:
    """Installs the handlers for its `with` block (only in the main thread: elsewhere it does nothing). A signal the
    process was started ignoring (SIGHUP under `nohup`, SIGINT in a background job) stays ignored."""

    def __init__(self) -> None:
        self._previous: dict[int, object] = {}
        self._holding = False
        self.pending: int | None = None  # the signal that came (while held, or raised and maybe lost)
        self._previous_hook = None  # sys.unraisablehook before __enter__

    def __enter__(self) -> Stopper:
        if threading.current_thread() is threading.main_thread():
            for signum in HANDLED:
                if signal.getsignal(signum) is signal.SIG_IGN:
                    continue  # ignored by whoever started us (`nohup` ignores SIGHUP): it stays ignored
                self._previous[signum] = signal.signal(signum, self._handle)
            self._previous_hook = sys.unraisablehook
            sys.unraisablehook = self._unraisable
        return self

    def __exit__(self, *exc) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)
        self._previous.clear()
        if self._previous_hook is not None:
            sys.unraisablehook = self._previous_hook
            self._previous_hook = None

    def _unraisable(self, unraisable) -> None:
        """A Signalled raised while Python ran a finalizer or a weakref callback cannot stop the run there; Python
        would print it with a traceback. `pending` keeps it for the next held() block: nothing is printed."""
        if isinstance(unraisable.exc_value, Signalled):
            return
        self._previous_hook(unraisable)

    def _handle(self, signum, _frame) -> None:
        # kept whether or not the exception below gets through: one raised while Python runs a finalizer or a
        # callback is printed and dropped, and the next held() block then stops the run all the same
        self.pending = signum
        if not self._holding:
            raise Signalled(signum)

    @contextmanager
    def held(self):
        """Defer signals until the block is done, then stop."""
        self._holding = True
        try:
            yield
        finally:
            self._holding = False
        if self.pending is not None:
            raise Signalled(self.pending)

    @contextmanager
    def deferred(self):
        """Defer signals until the block is done and do not stop: `pending` says which one came."""
        self._holding = True
        try:
            yield
        finally:
            self._holding = False


def exit_code(exc: KeyboardInterrupt) -> int:
    """128 + the signal's number (130 for Ctrl-C, 143 for SIGTERM, 129 for SIGHUP)."""
    return 128 + getattr(exc, "signum", signal.SIGINT)
