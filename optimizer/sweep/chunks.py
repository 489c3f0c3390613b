"""Cutting a plan into chunks: the unit of a task, of a Parquet part and of resume.

The numbers of a design do not depend on its chunk (``optimizer.sweep.fly_rows``), so
the size is a matter of overhead only: big enough that the scheduler's cost per task
(milliseconds) is small beside the flying (about a millisecond per design and maneuver
in a batch flight),
small enough that every worker gets several chunks and an interrupted sweep loses little.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import pandas as pd

from optimizer.errors import RequestError
from optimizer.sweep.fly_rows import Chunk

#: the most designs in one chunk unless ``--chunk-size`` says otherwise: a batch flight
#: of 1024 designs flies about twice as many per CPU second as one of 256
#: (benchmarks/flight_batch_bench.py), and a lost chunk costs seconds, not minutes
DEFAULT_CHUNK_SIZE = 1024
#: the fewest designs in a default chunk: a batch flight costs about 0.12 ms a tick
#: whatever its size (0.47 s for a 4 s maneuver, as much as flying 400 designs more;
#: benchmarks/sweep_bench.py), so smaller chunks only add that
MIN_CHUNK_SIZE = 256
#: chunks per worker slot the default size aims at (load balance at the end of a sweep)
CHUNKS_PER_SLOT = 4


def chunk_size(n_designs: int, slots: int, given: int | None = None) -> int:
    """``given`` (checked), else :data:`DEFAULT_CHUNK_SIZE` or less, so that each of
    ``slots`` parallel workers gets about :data:`CHUNKS_PER_SLOT` chunks, but not below
    :data:`MIN_CHUNK_SIZE` (a small sweep is then fewer chunks than slots)."""
    if given is not None:
        return check_chunk_size(given)
    share = math.ceil(n_designs / (CHUNKS_PER_SLOT * max(1, slots)))
    return max(1, min(DEFAULT_CHUNK_SIZE, max(MIN_CHUNK_SIZE, share)))


def check_chunk_size(given: int) -> int:
    """``--chunk-size``: a number of designs >= 1."""
    if given < 1:
        raise RequestError(f"--chunk-size: expected a number of designs >= 1, got {given}")
    return given


def split(plan: pd.DataFrame, maneuvers: Sequence[str], size: int, samples: int = 1,
          seed: int = 0) -> list[Chunk]:
    """Consecutive chunks of at most ``size`` plan rows, in plan order."""
    return [Chunk(plan.iloc[start:start + size].reset_index(drop=True), tuple(maneuvers),
                  samples, seed)
            for start in range(0, len(plan), size)]
