"""The objects alive when a run starts are left out of the cyclic collector during it.

Why: a full collection walks every tracked object (about 80 000 once numpy, scipy, pandas,
pyarrow and the bench are imported) while holding the interpreter lock, 40-65 ms of one
core, and longer on a loaded machine where the collecting thread is preempted meanwhile.
Every reader thread of the bench (an MSP poll every 1.7 ms at time scale 6, a reference
IMU's stream) waits that long. Frozen (``gc.freeze``), those objects are not walked; the
run's own garbage is still collected. They are handed back (``gc.unfreeze``) when the
last run in the process ends.
"""

from __future__ import annotations

import gc

from bench.engine.process_wide import ProcessWide

__all__ = ["FrozenHeap"]


class FrozenHeap(ProcessWide):
    """``with FrozenHeap():`` freezes the heap on the first entry and unfreezes it at the
    last exit (runs in threads of one process may overlap)."""

    def _begin(self) -> None:
        gc.freeze()

    def _end(self) -> None:
        gc.unfreeze()
