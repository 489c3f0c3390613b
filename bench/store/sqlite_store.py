"""Opening and writing the SQLite files beside the runs (run index, constants store).

Both stores tell two faults apart that SQLite reports alike: a file that is not a
database (move it away, rebuild) and a store that cannot be written (read-only file or
folder, full disk, locked). Mixing them up sent users to delete a good store that only
lived on a read-only medium.
"""

from __future__ import annotations

import contextlib
import sqlite3
from collections.abc import Iterator
from pathlib import Path

from bench.errors import RigError

__all__ = ["connect", "writing"]


def connect(path: Path, schema: str, what: str, broken_hint: str, *,
            read_only: bool = False) -> sqlite3.Connection:
    """A connection to the store at ``path`` with its table created if missing; with
    ``read_only`` SQLite opens the file read-only (nothing created, nothing written)."""
    if read_only:
        return _connect_read_only(path, what, broken_hint)
    try:
        con = sqlite3.connect(path, timeout=10.0)
        con.execute(schema)
    except sqlite3.OperationalError as exc:  # read-only, cannot create, locked, disk full
        raise RigError(f"{path}: cannot open the {what} ({exc}); check that {path.parent} "
                       f"and {path.name} are writable") from None
    except sqlite3.DatabaseError as exc:  # not a database, malformed
        raise RigError(f"{path}: not a readable {what} ({exc}); {broken_hint}") from None
    return con


def _connect_read_only(path: Path, what: str, broken_hint: str) -> sqlite3.Connection:
    try:
        con = sqlite3.connect(f"{Path(path).resolve().as_uri()}?mode=ro", uri=True,
                              timeout=10.0)
        con.execute("SELECT count(*) FROM sqlite_master")
    except sqlite3.DatabaseError as exc:  # missing, unreadable, not a database
        raise RigError(f"{path}: not a readable {what} ({exc}); {broken_hint}") from None
    return con


@contextlib.contextmanager
def writing(path: Path, what: str) -> Iterator[None]:
    """A write to the store; a read-only store or full disk becomes one ``RigError``."""
    try:
        yield
    except sqlite3.OperationalError as exc:
        raise RigError(f"{path}: cannot write the {what} ({exc}); it is read-only, locked "
                       "or the disk is full") from None
