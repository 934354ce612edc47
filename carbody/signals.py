"""Stopping a command cleanly: SIGINT (Ctrl-C), SIGTERM and SIGHUP become exceptions in the main
thread, so every ``finally`` runs and what a run had staged goes, and a step that must be done
whole (a file made and noted for removal, the outputs moved into place) holds them until it ends.

The ``carbody`` command installs the handlers (:func:`handlers`); a Python caller keeps its own,
and :func:`held` is then a plain block.
"""
from __future__ import annotations

import contextlib
import signal
from collections.abc import Iterator

#: The signals that stop a command.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class Stopped(BaseException):
    """The process was told to stop (SIGTERM, SIGHUP): raised like KeyboardInterrupt (which
    SIGINT still raises), past ``except Exception``, so every ``finally`` runs."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


_state = {"installed": False, "holding": 0, "pending": None}


def _stop(signum: int, frame) -> None:
    if _state["holding"]:
        _state["pending"] = _state["pending"] or signum
        return
    _raise(signum)


def _raise(signum: int) -> None:
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise Stopped(signum)


@contextlib.contextmanager
def handlers() -> Iterator[None]:
    """The stop signals raise in the main thread for the block; the previous handlers after it."""
    previous = {signum: signal.signal(signum, _stop) for signum in STOP_SIGNALS}
    _state["installed"] = True
    try:
        yield
    finally:
        _state["installed"] = False
        for signum, handler in previous.items():
            signal.signal(signum, handler)


@contextlib.contextmanager
def held() -> Iterator[None]:
    """A stop signal that comes during the block stops the command when the block ends."""
    if not _state["installed"]:
        yield
        return
    _state["holding"] += 1
    try:
        yield
    finally:
        _state["holding"] -= 1
        pending, _state["pending"] = (_state["pending"], None) if not _state["holding"] else (None, _state["pending"])
        if pending is not None:
            _raise(pending)
