"""Run ids that are unique across benches and sort by start time (UUIDv7, RFC 9562).

Two benches that start a run in the same microsecond still get different ids: 74 of the
128 bits are random. A run id keeps the readable stamp in front and the name at the end
and carries 8 hex digits of the UUID between them (``bench.run.recorder.new_run_id``):
``20261127T081500_123456Z-9f3c01d2-step1``.
"""

from __future__ import annotations

import os
import time
import uuid

__all__ = ["uuid7"]


def uuid7(unix_ms: int | None = None) -> uuid.UUID:
    """A version-7 UUID: 48 bits of Unix milliseconds, then random bits (RFC 9562 5.7)."""
    ms = int(time.time() * 1000) if unix_ms is None else int(unix_ms)
    rand = int.from_bytes(os.urandom(10), "big")
    value = (ms & ((1 << 48) - 1)) << 80 | rand & ((1 << 80) - 1)
    value = (value & ~(0xF << 76)) | (0x7 << 76)          # version 7
    value = (value & ~(0x3 << 62)) | (0x2 << 62)          # variant 10
    return uuid.UUID(int=value)
