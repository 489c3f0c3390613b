"""Output folders a command replaces as a whole (``report --out``, ``demo --out``).

A command that builds its folder beside the target and renames it into place would
delete whatever else the user keeps there (notes, a folder of their own data). So the
command lists every file it wrote in a manifest inside the folder, and a later run
replaces the folder only when it holds nothing outside that list; otherwise it refuses,
naming what it would have deleted. Folders written before the manifest existed are
judged by the command's own top-level names (``legacy``).
"""

from __future__ import annotations

import fnmatch
import os
from collections.abc import Sequence
from pathlib import Path

from bench.errors import RigError

__all__ = ["MANIFEST", "refuse_foreign", "write_manifest"]

#: The manifest file: one relative POSIX path a line, every file the command wrote.
MANIFEST = ".rotorbench-files"


def write_manifest(folder: Path) -> None:
    """List every file under ``folder`` (written last, so it names the finished folder)."""
    names = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*")
                   if p.is_file() and not p.is_symlink())
    (folder / MANIFEST).write_text("".join(f"{n}\n" for n in [*names, MANIFEST]),
                                   encoding="utf-8")


def _foreign(folder: Path, legacy: Sequence[str]) -> list[str]:
    """Entries under ``folder`` its command did not write (relative, folders end in /)."""
    manifest = folder / MANIFEST
    if not manifest.is_file():  # an older folder: its own top-level names only
        return sorted(f"{e.name}/" if e.is_dir() and not e.is_symlink() else e.name
                      for e in folder.iterdir()
                      if not any(fnmatch.fnmatchcase(e.name, pat) for pat in legacy))
    own = set(manifest.read_text(encoding="utf-8", errors="replace").splitlines())
    own_dirs = {q.as_posix() for n in own for q in Path(n).parents}
    found = []
    for root, dirs, files in os.walk(folder):
        rel = Path(root).relative_to(folder)
        for d in list(dirs):
            r = (rel / d).as_posix()
            if r not in own_dirs or (Path(root) / d).is_symlink():
                found.append(f"{r}/")
                dirs.remove(d)  # one entry for a foreign folder, not its contents
        found.extend(r for f in files if (r := (rel / f).as_posix()) not in own)
    return sorted(found)


def refuse_foreign(folder: Path, flag: str, command: str, legacy: Sequence[str]) -> None:
    """Refuse (exit 2) to replace ``folder`` when it holds anything ``command`` did not
    write; ``legacy`` are the glob patterns of its top-level names before the manifest."""
    if not folder.is_dir():
        return
    foreign = _foreign(folder, legacy)
    if foreign:
        shown = ", ".join(foreign[:3]) + (f" and {len(foreign) - 3} more"
                                          if len(foreign) > 3 else "")
        raise RigError(f"{flag} {folder}: holds files `rotorbench {command}` did not write "
                       f"({shown}); refusing to replace the folder: move them out or "
                       "choose a new folder")
