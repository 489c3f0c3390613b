"""Does a chunk of ``--samples M`` fit in memory? Refused before anything flies if not.

A robust sweep flies each design with measured spreads M times in one batch: its
drawn constants, the batch's numbers and one figures dict per flown sample stay in
memory together (measured: about 1 kB per flown sample beyond the batch flight's own
ticks, which ``optimizer.flight.batch`` caps). Every design, drawn or not, then takes
its percentiles over M values (about 25 bytes each). ``--samples 1e9`` asked for tens
of GiB and died with a MemoryError deep in numpy, so the bytes a chunk needs are counted
from the plan, the chunk size and M, and compared with what one worker slot has: the
memory this machine has available in this process, a Dask worker's memory limit (or
its machine's available memory) over its threads on a cluster.
"""

from __future__ import annotations

import os
from collections.abc import Iterable

import numpy as np
import pandas as pd

from bench.errors import RigError
from optimizer.sweep.flight_params import STD_PREFIX

#: bytes per flown sample: its draws, its row of the batch's numbers, its figures dict
#: (tracemalloc: 1030 per sample past the batch flight's 4096-design cap, roll_step)
BYTES_PER_FLOWN_SAMPLE = 1000
#: bytes per sample of a design's percentiles (25 per sample by tracemalloc and by the
#: resident size at M = 1e7 and 5e7, a design without spreads: its one flight stands
#: for all M)
BYTES_PER_PERCENTILE_SAMPLE = 25


def available_memory() -> int | None:
    """The bytes this machine can give a process now without swapping: psutil's
    ``available`` (Linux's MemAvailable: free memory and the cache it may drop), else
    the free pages; None where the OS does not say. Not the physical total: other
    processes hold part of it (the total let ``--samples 1e9`` through on a 23.5 GiB
    machine, whose kernel then killed the sweep)."""
    try:
        import psutil
    except ImportError:
        try:
            return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
        except (ValueError, OSError, AttributeError):
            return None
    return int(psutil.virtual_memory().available)


def drawn(plan: pd.DataFrame) -> np.ndarray:
    """Per design: whether it has a measured spread, so flies every sample."""
    cols = [c for c in plan.columns if c.startswith(STD_PREFIX)]
    if not cols:
        return np.zeros(len(plan), bool)
    return np.asarray((plan[cols].to_numpy(float) > 0).any(axis=1))


def chunk_bytes(designs: int, drawn_designs: int, samples: int) -> int:
    """Bytes one chunk of ``designs`` (``drawn_designs`` of them with spreads) needs."""
    if samples <= 1:
        return designs * BYTES_PER_FLOWN_SAMPLE
    flown = designs + drawn_designs * (samples - 1)
    return flown * BYTES_PER_FLOWN_SAMPLE + samples * BYTES_PER_PERCENTILE_SAMPLE


def most_samples(designs: int, drawn_designs: int, memory: int) -> int:
    """The largest ``--samples`` whose chunk fits in ``memory`` bytes (0: none)."""
    fixed = (designs - drawn_designs) * BYTES_PER_FLOWN_SAMPLE
    per = drawn_designs * BYTES_PER_FLOWN_SAMPLE + BYTES_PER_PERCENTILE_SAMPLE
    return max(0, (memory - fixed) // per)


def check_fits(plan: pd.DataFrame, size: int, samples: int, memory: int | None,
               where: str) -> None:
    """Refuse (``RigError``, exit 2) ``samples`` if the biggest chunk of ``plan`` cut in
    ``size`` designs needs more than ``memory`` bytes (``where``: whose memory, e.g.
    ``"on this machine"``)."""
    if memory is None or samples <= 1 or plan.empty:
        return
    spread = drawn(plan)
    chunks: Iterable[tuple[int, int]] = (
        (len(spread[i:i + size]), int(spread[i:i + size].sum()))
        for i in range(0, len(plan), size))
    designs, drawn_designs = max(chunks, key=lambda c: chunk_bytes(*c, samples))
    need = chunk_bytes(designs, drawn_designs, samples)
    if need <= memory:
        return
    fits = most_samples(designs, drawn_designs, memory)
    raise RigError(f"--samples {samples}: a chunk of {designs} designs ({drawn_designs} with "
                   f"measured spreads) needs about {_size(need)} of memory, {_size(memory)} is "
                   f"available {where}; at most --samples {fits} fits"
                   + (" (or a smaller --chunk-size)" if drawn_designs > 1 else ""))


def _size(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if n < 1024 or unit == "PiB":
            return f"{n:.1f} {unit}" if unit != "B" else f"{int(n)} B"
        n /= 1024
    return f"{n:.1f} PiB"
