"""One sweep at a time per output file: an OS advisory lock beside ``--out``.

Two sweeps writing the same ``SWEEP.parquet`` would share its parts folder: one removes
the other's temporary files on start, the first to finish removes the folder under the
other. So a sweep holds ``fcntl.flock`` on ``SWEEP.parquet.lock`` while it runs and a
second one is refused in one line (exit 2) naming the process that holds it. The kernel
releases the lock when its process ends, however it ends, so a killed sweep never
leaves a stale lock: the next run takes the file over.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
from collections.abc import Iterator
from pathlib import Path

from bench.errors import RigError

#: the lock file's name beside the output: ``<out>.lock``
LOCK_SUFFIX = ".lock"


def lock_path(out: Path) -> Path:
    """Where the lock of the sweep writing ``out`` lives."""
    return out.with_name(out.name + LOCK_SUFFIX)


@contextlib.contextmanager
def sweep_lock(out: Path) -> Iterator[Path]:
    """Hold the lock of ``out``'s sweep for the block, or refuse (``RigError``) while
    another process holds it. The file is removed on the way out while still locked;
    a process that opened it just before finds it unlinked and takes the new one."""
    path = lock_path(out)
    fd = _acquire(path, out)
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        yield path
    finally:
        with contextlib.suppress(OSError):
            path.unlink()
        os.close(fd)  # closing the last descriptor releases the lock


def _acquire(path: Path, out: Path) -> int:
    """A descriptor of ``path`` locked by this process (retried while the file it opened
    was replaced or removed by the previous holder between open and lock)."""
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise RigError(f"--out {out}: cannot create its lock file {path} "
                           f"({exc.strerror or exc})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _holder(fd)
            os.close(fd)
            raise RigError(f"--out {out}: another sweep is writing it{holder} (lock "
                           f"{path}); wait for it to end or choose another --out") from None
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if same:
            return fd
        os.close(fd)


def _holder(fd: int) -> str:
    """`` (process N)`` from the lock file, or nothing when it holds no pid yet."""
    with contextlib.suppress(OSError, ValueError):
        pid = int(os.pread(fd, 32, 0).decode().strip())
        return f" (process {pid})"
    return ""
