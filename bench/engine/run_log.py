"""The run's diagnostic log: ``run.log`` beside ``run.json``.

``run.json`` says how a run ended; ``run.log`` says what happened on the way, for the
person who has to find out why: the rig opened, the devices that answered, each segment,
the watchdog check-ins that came late and where the loop was, the reason for the stop.

Every module logs to its own ``logging.getLogger(__name__)``. A run is captured from
before its devices open (``capture``), when there is no run folder yet: the lines wait in
memory until the recorder makes the folder (``attach``), then go to the file as they come,
from every thread (the watchdog's, the device readers'), until the run ends. The capture
lowers the project's loggers to DEBUG only while it lasts, so a program that uses
rotorbench as a library sees its logging settings unchanged outside a run; what reaches
the terminal is the CLI's choice (``-v``, ``--log-level``), never the file's.
"""

from __future__ import annotations

import contextlib
import contextvars
import logging
from collections.abc import Iterator
from pathlib import Path

__all__ = ["LOG_NAME", "PACKAGES", "RunLogCapture", "attach", "capture"]

LOG_NAME = "run.log"
#: the project's top-level loggers (each module's logger is a child of one of them)
PACKAGES = ("bench", "drivers", "analysis", "optimizer")
FORMAT = "%(asctime)s.%(msecs)03d %(levelname)-7s %(threadName)s %(name)s: %(message)s"
DATEFMT = "%Y-%m-%dT%H:%M:%S"
#: lines kept in memory before the run folder exists (the rig's bring-up); more are counted
PREAMBLE_MAX = 2000

_current: contextvars.ContextVar[RunLogCapture | None] = contextvars.ContextVar(
    "rotorbench_run_log", default=None)


class RunLogCapture(logging.Handler):
    """Holds a run's lines in memory until its folder exists, then writes ``run.log``."""

    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.setFormatter(logging.Formatter(FORMAT, DATEFMT))
        self._pending: list[str] = []
        self._dropped = 0
        self._file: logging.FileHandler | None = None
        self.path: Path | None = None

    def emit(self, record: logging.LogRecord) -> None:
        if self._file is not None:
            self._file.emit(record)
            return
        if len(self._pending) < PREAMBLE_MAX:
            self._pending.append(self.format(record))
        else:
            self._dropped += 1

    def attach(self, run_dir: Path) -> None:
        """Write what waited into ``run_dir/run.log`` and follow the run there. A second
        run under the same capture (a calibration's stages) gets its own file."""
        self.detach()
        path = Path(run_dir) / LOG_NAME
        try:
            handler = logging.FileHandler(path, encoding="utf-8", delay=False)
        except OSError:  # the run folder cannot take it: the run itself says so
            return
        handler.setFormatter(self.formatter)
        stream = handler.stream
        assert stream is not None  # delay=False: the handler opened its file
        with contextlib.suppress(OSError):
            for line in self._pending:
                stream.write(line + "\n")
            if self._dropped:
                stream.write(f"... {self._dropped} earlier lines not kept\n")
            handler.flush()
        self._pending, self._dropped = [], 0
        self._file, self.path = handler, path

    def detach(self) -> None:
        """Close the file; later lines wait in memory for the next run, if any."""
        if self._file is not None:
            with contextlib.suppress(OSError):
                self._file.close()
            self._file = None

    def close(self) -> None:
        self.detach()
        super().close()


@contextlib.contextmanager
def capture() -> Iterator[RunLogCapture]:
    """Capture the project's log lines for the run (or runs) made inside; nested calls
    share the outer capture, so a command that records several runs writes each its own."""
    outer = _current.get()
    if outer is not None:
        yield outer
        return
    handler = RunLogCapture()
    loggers = [logging.getLogger(name) for name in PACKAGES]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.addHandler(handler)
        lg.setLevel(logging.DEBUG)
    token = _current.set(handler)
    try:
        yield handler
    finally:
        _current.reset(token)
        for lg, level in zip(loggers, levels, strict=True):
            lg.removeHandler(handler)
            lg.setLevel(level)
        handler.close()


def attach(run_dir: Path) -> None:
    """Send the current capture's lines to ``run_dir/run.log`` (no capture: nothing)."""
    handler = _current.get()
    if handler is not None:
        handler.attach(run_dir)


def detach() -> None:
    """The run in the current capture has ended: close its ``run.log``."""
    handler = _current.get()
    if handler is not None:
        handler.detach()
