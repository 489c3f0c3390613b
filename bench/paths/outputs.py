"""Output paths a command writes, checked before any work.

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
from collections.abc import Sequence
from pathlib import Path

from bench.errors import RigError
from bench.paths.inputs import refuse_loop
from optimizer.errors import RequestError

__all__ = ["FIGURE_SUFFIXES", "check_figure_path", "check_folder_to_read", "check_writable",
           "permits_writing"]


def check_folder_to_read(path: Path, flag: str = "--out") -> Path:
    """A folder a command lists (runs, constants): a file there is a mistake said now,
    a folder not made yet simply holds nothing."""
    path = Path(path)
    # exists() is False for a loop: it read as an empty folder
    refuse_loop(path, f"{flag} {path}", "a folder of runs")
    if path.exists() and not path.is_dir():
        raise RigError(f"{flag} {path}: is a file; expected a folder of runs")
    return path


#: figure formats a ``--plot FILE`` may name (matplotlib's Agg backend writes them)
FIGURE_SUFFIXES = (".png", ".pdf", ".svg")


def check_figure_path(path: Path, flag: str = "--plot",
                      suffixes: tuple[str, ...] = FIGURE_SUFFIXES,
                      inputs: Sequence[Path | None] = ()) -> Path:
    """Refuse, before any work, a figure file that could not be written or whose suffix is
    no figure format (matplotlib would append ``.png`` to a bare name, or fail late);
    ``suffixes``: the formats the writer knows (default: matplotlib's); ``inputs``: the
    files the command reads (never overwritten)."""
    path = Path(path)
    if path.suffix.lower() not in suffixes:
        raise RequestError(f"{flag} {path}: expected a file name ending in "
                           f"{', '.join(suffixes)}")
    return check_writable(path, flag, folder=False, inputs=inputs)


def check_writable(path: Path, flag: str, *, folder: bool, beside: bool = False,
                   make_parents: bool = True, inputs: Sequence[Path | None] = ()) -> Path:
    """Refuse (``RigError``) an output ``path`` that cannot be written; return it.

    ``folder``: the output is a folder (a run root, a report) rather than a file.
    ``beside``: the folder is built beside its final name and renamed into place, so
    its parent must be writable even when the folder exists.
    ``make_parents``: the command creates missing parent folders; if not, the parent
    must exist.
    ``inputs``: the files the command reads; an output that is one of them is refused
    (writing it would replace the data it is computed from).
    """
    path = Path(path)
    where = f"{flag} {path}" if flag else str(path)
    for source in inputs:
        if source is not None and _same_file(path, Path(source)):
            raise RigError(f"{where}: is also an input ({source}); choose another name "
                           "for the output")
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


def _same_file(a: Path, b: Path) -> bool:
    """Whether ``a`` and ``b`` name the same file (through links, ``..`` and case)."""
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def _probe(folder: Path) -> str | None:
    """Why a new file cannot be created in ``folder`` (None if it can)."""
    try:
        fd, name = tempfile.mkstemp(prefix=".rotorbench-probe-", dir=folder)
    except OSError as exc:
        return exc.strerror or str(exc)
    os.close(fd)
    os.unlink(name)
    return None


def permits_writing(path: Path) -> bool:
    """Whether ``path``'s permissions let this user write it (``os.access``): the quick
    choice of where a new file goes (beside a rig, or in a copy), never a refusal, which
    :func:`check_writable` makes by probing."""
    return os.access(path, os.W_OK)
