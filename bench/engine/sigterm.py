"""``kill PID`` (SIGTERM) ends a command like Ctrl-C: the same safe stop, record and clean-up
(``finally`` blocks run), then exit 143 instead of 130. Without a handler Python dies by the
signal on the spot: a console session stayed 'running' with no safe stop, a demo left its
temporary folder."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator

__all__ = ["sigterm_as_interrupt"]


@contextlib.contextmanager
def sigterm_as_interrupt(stop: threading.Event | None = None) -> Iterator[None]:
    """SIGTERM raises ``KeyboardInterrupt("SIGTERM")`` in the main thread (``bench.cli``
    maps it to 143), after setting ``stop`` for a run going on in another thread."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def on_term(*_: object) -> None:
        if stop is not None:
            stop.set()
        raise KeyboardInterrupt("SIGTERM")  # a runner on this thread: interrupt it now

    previous = signal.signal(signal.SIGTERM, on_term)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
