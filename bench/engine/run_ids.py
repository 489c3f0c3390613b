"""Run ids: unique across benches, sorted by start time (UUIDv7, RFC 9562), and safe as
one path component.

Two benches that start a run in the same microsecond still get different ids: 74 of the
128 bits are random. A run id keeps the readable stamp in front and the name at the end
and carries 8 hex digits of the UUID between them (``bench.engine.recorder.new_run_id``):
``20261127T081500_123456Z-9f3c01d2-step1``.

A run id names a folder in a store, a spool, a cache and an object key, and it arrives
from places other people write (a copied run folder's ``run.json``, a catalog row, a URL).
``check_run_id`` is the one test every entry applies: letters, digits and ``_ . : + -``,
starting with a letter or digit, no ``..``, at most ``RUN_ID_MAX`` characters; so no
``/``, ``\\``, NUL or ``..`` can make a path leave its folder. ``run_id_name`` makes a
sequence's name fit the same rule before it becomes part of a new id.
"""

from __future__ import annotations

import os
import re
import time
import uuid

from bench.errors import RigError

__all__ = ["RUN_ID_MAX", "check_run_id", "is_run_id", "run_id_name", "uuid7"]

RUN_ID_MAX = 128
_RUN_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.:+-]*")
_NOT_IN_ID = re.compile(r"[^A-Za-z0-9_.:+-]+")
#: the stamp and the hex digits ``new_run_id`` puts before the name
_ID_PREFIX = len("20261127T081500_123456Z-9f3c01d2-")


def uuid7(unix_ms: int | None = None) -> uuid.UUID:
    """A version-7 UUID: 48 bits of Unix milliseconds, then random bits (RFC 9562 5.7)."""
    ms = int(time.time() * 1000) if unix_ms is None else int(unix_ms)
    rand = int.from_bytes(os.urandom(10), "big")
    value = (ms & ((1 << 48) - 1)) << 80 | rand & ((1 << 80) - 1)
    value = (value & ~(0xF << 76)) | (0x7 << 76)          # version 7
    value = (value & ~(0x3 << 62)) | (0x2 << 62)          # variant 10
    return uuid.UUID(int=value)


def is_run_id(text: object) -> bool:
    """True when ``text`` is a run id that is safe as one path component."""
    return (isinstance(text, str) and len(text) <= RUN_ID_MAX and ".." not in text
            and _RUN_ID.fullmatch(text) is not None)


def check_run_id(text: object, where: str) -> str:
    """``text`` if it is a run id, else ``RigError`` naming ``where`` it came from (the
    id is quoted cut short, control characters escaped)."""
    if is_run_id(text):
        return str(text)
    from analysis.errors import excerpt

    raise RigError(f"{where}: {excerpt(text)} is not a run id (letters, digits and _ . : + -, "
                   f"starting with a letter or digit, no '..', at most {RUN_ID_MAX} "
                   "characters)")


def run_id_name(name: str) -> str:
    """``name`` (a sequence's, from a rig or plan file) as the end of a run id: other
    characters become ``-``, ``..`` one dot, cut so the whole id fits ``RUN_ID_MAX``."""
    text = re.sub(r"\.{2,}", ".", _NOT_IN_ID.sub("-", str(name)))
    return text[:RUN_ID_MAX - _ID_PREFIX] or "run"
