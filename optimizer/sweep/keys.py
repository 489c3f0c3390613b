"""The keys that name a design in a sweep, its stable id and its random seed.

The id is a hash of the keys alone (not of a position or a chunk), so it is the same in
every run, worker count and chunking: resume finds finished designs by it, and
uncertainty sampling (``--samples``) seeds each design's draws from it, so a design's
samples do not depend on which worker flies it or with which neighbours.
"""

from __future__ import annotations

import hashlib
import json

#: A design: actuator count, propeller, motor, battery (a plain catalog's battery id, or
#: the cell of a series/parallel pack) and the pack's cells in series and in parallel.
DESIGN_KEYS: tuple[str, ...] = ("actuators", "propeller", "motor", "battery", "series",
                                "parallel")


def design_id(actuators: int, propeller: str, motor: str, battery: str, series: int,
              parallel: int) -> str:
    """16 hex digits of SHA-256 over the keys (64 bits: a collision among ten million
    designs has odds of about 3e-6, and the plan refuses one)."""
    text = json.dumps([int(actuators), str(propeller), str(motor), str(battery), int(series),
                       int(parallel)], separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def design_seed(design: str) -> int:
    """The design's random seed (0 <= seed < 2**64) from its id: what a design's samples
    are drawn with (``numpy.random.default_rng(seed)``), whoever flies it."""
    return int(design, 16)
