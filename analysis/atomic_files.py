"""Write a file or folder atomically (a hidden temporary beside it, then a rename) with the
permissions a plain ``open()`` or ``mkdir()`` would give.

``tempfile.mkstemp`` creates 0600 files and ``mkdtemp`` 0700 folders, whatever the umask:
a calibration, a log or a report written that way is unreadable to the user's group, and
replacing a file (a rig's thrust map) silently tightened its mode. Here the temporary is
created exclusively with 0666/0777 so the kernel applies the umask, and when it replaces
an existing file it takes that file's mode. Every atomic writer of the project goes
through :func:`write_atomically` (files) or :func:`temp_beside` (folders renamed into
place by their command).
"""

from __future__ import annotations

import os
import secrets
import shutil
import stat
from collections.abc import Callable
from pathlib import Path

__all__ = ["temp_beside", "write_atomically"]


def temp_beside(path: Path, suffix: str = ".tmp", *, folder: bool = False) -> Path:
    """A new hidden file (or folder) beside ``path`` with the umask's mode, or the mode of
    ``path`` when it exists (a replacement keeps the permissions the user gave)."""
    path = Path(path)
    for _ in range(100):
        tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}{suffix}"
        try:
            if folder:
                tmp.mkdir(mode=0o777)
            else:
                os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        except FileExistsError:
            continue
        try:
            if path.exists() and path.is_dir() == folder:
                os.chmod(tmp, stat.S_IMODE(path.stat().st_mode))
        except OSError:  # a mode that cannot be copied: the umask's stands
            pass
        return tmp
    raise FileExistsError(f"{path.parent}: no free temporary name beside {path.name}")


def write_atomically(path: str | Path, write: Callable[[Path], object], *,
                     suffix: str = ".tmp", fsync: bool = False) -> Path:
    """Call ``write(tmp)`` on a temporary beside ``path``, then rename it onto ``path``;
    on any error (or Ctrl-C) the temporary is removed and ``path`` is untouched.
    ``fsync``: flush the data to the disk before the rename (files that must survive a
    power cut whole, e.g. a rig file)."""
    path = Path(path)
    tmp = temp_beside(path, suffix)
    try:
        write(tmp)
        if fsync:
            fd = os.open(tmp, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        if tmp.is_dir():
            shutil.rmtree(tmp, ignore_errors=True)
        else:
            tmp.unlink(missing_ok=True)
        raise
    return path
