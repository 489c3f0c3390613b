"""The keys that name a design in a sweep and its stable id.

The id is a hash of the keys alone (not of a position or a chunk), so it is the same in
every run, worker count and chunking: resume finds finished designs by it. Uncertainty
sampling (``--samples``) seeds each design's draws from the same keys
(``optimizer.flight.uncertainty.design_seed``), so a design's samples do not depend on
which worker flies it or with which neighbours.
"""

from __future__ import annotations

import hashlib
import json

from optimizer.flight.uncertainty import DESIGN_KEYS as UNCERTAINTY_KEYS

#: A design: actuator count, propeller, motor, battery (a plain catalog's battery id, or
#: the cell of a series/parallel pack) and the pack's cells in series and in parallel
#: (its seed, ``optimizer.flight.uncertainty.design_seed``, hashes the same keys).
DESIGN_KEYS: tuple[str, ...] = UNCERTAINTY_KEYS


def design_id(actuators: int, propeller: str, motor: str, battery: str, series: int,
              parallel: int) -> str:
    """16 hex digits of SHA-256 over the keys (64 bits: a collision among ten million
    designs has odds of about 3e-6, and the plan refuses one)."""
    text = json.dumps([int(actuators), str(propeller), str(motor), str(battery), int(series),
                       int(parallel)], separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]
