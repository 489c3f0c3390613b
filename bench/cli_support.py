"""Helpers every CLI command shares (the one home: commands never import each other).

The output check every writing command makes on its output path before any work.

A command that would run for minutes (a demo, a calibration on the rig) and then fail to
write its result wastes the run; a traceback at the end says nothing useful. So each
command names its outputs up front and :func:`check_writable` refuses, in one line with
exit code 2, a path that cannot be written: a regular file where a folder must be (or
the reverse), a missing folder the command does not create, a folder the user may not
write in (read-only, immutable, read-only file system). Writability is probed by creating
and removing a hidden temporary file, the only test that is right for every user
(``os.access`` says yes to root on a read-only folder, no on some network mounts).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from bench.errors import RigError

__all__ = ["check_writable"]


def check_writable(path: Path, flag: str, *, folder: bool, beside: bool = False,
                   make_parents: bool = True) -> Path:
    """Refuse (``RigError``) an output ``path`` that cannot be written; return it.

    ``folder``: the output is a folder (a run root, a report) rather than a file.
    ``beside``: the folder is built beside its final name and renamed into place, so
    its parent must be writable even when the folder exists.
    ``make_parents``: the command creates missing parent folders; if not, the parent
    must exist.
    """
    path = Path(path)
    where = f"{flag} {path}" if flag else str(path)
    if path.exists() or path.is_symlink():
        if folder and not path.is_dir():
            raise RigError(f"{where}: is a file; expected a folder")
        if not folder and path.is_dir():
            raise RigError(f"{where}: is a folder; expected the name of the file to write")
    # where the new entries go: into an existing folder, else beside the path
    target = path if folder and path.is_dir() and not beside else path.parent
    anchor = target
    while not anchor.exists() and anchor != anchor.parent:
        anchor = anchor.parent  # the nearest folder that exists: the command creates the rest
    if not anchor.is_dir():
        raise RigError(f"{where}: {anchor} is a file, not a folder")
    if not make_parents and anchor != target:
        raise RigError(f"{where}: folder {target} does not exist")
    problem = _probe(anchor)
    if problem is not None:
        raise RigError(f"{where}: cannot write in {anchor} ({problem})")
    return path


def _probe(folder: Path) -> str | None:
    """Why a new file cannot be created in ``folder`` (None if it can)."""
    try:
        fd, name = tempfile.mkstemp(prefix=".rotorbench-probe-", dir=folder)
    except OSError as exc:
        return exc.strerror or str(exc)
    os.close(fd)
    os.unlink(name)
    return None
