"""What a sweep's LocalCluster worker processes load at start (``distributed`` preload).

Ctrl-C at a terminal reaches the whole process group, the workers too; the command closes
its cluster itself, so each worker ignores it instead of printing a traceback. Kept
apart and small: a worker imports it before anything else.
"""

from __future__ import annotations

import signal
from typing import Any


def dask_setup(worker: Any) -> None:
    """The preload hook ``distributed`` calls in each worker process."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
