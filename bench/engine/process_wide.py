"""A setting of the whole process held while any run in it lasts.

Why: runs in threads of one process may overlap (the console's, the tests'); a setting of
the process (the frozen heap, the raised priority) is made when the first of them starts
and undone when the last ends, never by one run under another's feet.
"""

from __future__ import annotations

import threading
from typing import ClassVar

__all__ = ["ProcessWide"]


class ProcessWide:
    """``with Sub():`` calls ``_begin`` at the first entry in the process and ``_end`` at
    the last exit, each subclass counting its own; an instance whose ``active`` is false
    does neither."""

    _lock: ClassVar[threading.Lock]
    _depth: ClassVar[int]
    active = True

    def __init_subclass__(cls) -> None:
        super().__init_subclass__()
        cls._lock = threading.Lock()
        cls._depth = 0

    def _begin(self) -> None:
        raise NotImplementedError

    def _end(self) -> None:
        raise NotImplementedError

    def __enter__(self) -> ProcessWide:
        if self.active:
            cls = type(self)
            with cls._lock:
                if cls._depth == 0:
                    self._begin()
                cls._depth += 1
        return self

    def __exit__(self, *exc: object) -> None:
        if self.active:
            cls = type(self)
            with cls._lock:
                cls._depth -= 1
                if cls._depth == 0:
                    self._end()
