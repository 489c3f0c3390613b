"""Files that a run folder's ``run.json`` names stay inside that run folder.

A run folder comes from whoever recorded, copied or pushed it, so ``run.json`` is input
like any log: its ``samples`` and ``events`` are names relative to the folder, never a
way to read another file. ``member`` turns such a name into a path and refuses an
absolute path, ``..``, a backslash or NUL, and a link whose target is outside the
folder; ``files_under`` lists a folder's files the same way (a samples folder of parts,
a whole run to upload); ``read_run_json`` reads ``run.json`` itself (not pandas: the
listings use it). Every refusal is a ``LogError`` that names the run's file, never what
the file holds.
"""

from __future__ import annotations

import json
import os
from pathlib import Path, PurePosixPath
from typing import Any

from analysis.errors import LogError, excerpt

__all__ = ["EVENTS_DEFAULT", "LOG_NAME", "NAME_MAX", "SAMPLES_DEFAULT", "check_inside",
           "events_path", "files_under", "log_path", "member", "read_log_tail",
           "read_run_json", "samples_path"]

NAME_MAX = 255
SAMPLES_DEFAULT = "samples.parquet"
EVENTS_DEFAULT = "events.csv"
LOG_NAME = "run.log"  # the run's diagnostic log (the recorder writes it beside run.json)


def member(run_dir: str | Path, name: object, what: str) -> Path:
    """``run_dir / name`` for a ``name`` given as ``what`` (``run.json's samples``),
    checked to stay inside ``run_dir`` (links followed)."""
    run_dir = Path(run_dir)
    text = name if isinstance(name, str) else ""
    pure = PurePosixPath(text)
    if (not text or len(text) > NAME_MAX or "\x00" in text or "\\" in text
            or pure.is_absolute() or ".." in pure.parts or pure == PurePosixPath(".")):
        raise LogError(f"{run_dir}: {what} {excerpt(name)} is not a file name inside the "
                       "run folder")
    path = run_dir / pure
    check_inside(run_dir, path)
    return path


def check_inside(run_dir: str | Path, path: str | Path) -> None:
    """``LogError`` when ``path`` (links followed) is not ``run_dir`` or inside it."""
    try:
        base, real = Path(run_dir).resolve(), Path(path).resolve()
    except (OSError, RuntimeError):  # a link loop
        raise LogError(f"{path}: a link that cannot be followed (not read)") from None
    if real != base and base not in real.parents:
        raise LogError(f"{path}: a link to outside the run folder {run_dir} (not read)")


def files_under(run_dir: str | Path, folder: str | Path | None = None) -> list[Path]:
    """Every file under ``folder`` (default: the run folder), sorted, as paths through
    ``folder``; a link is followed only when it stays inside ``run_dir`` (``LogError``
    otherwise), and each folder is listed once (a link loop ends)."""
    run_dir = Path(run_dir)
    top = Path(folder) if folder is not None else run_dir
    check_inside(run_dir, top)
    out: list[Path] = []
    seen: set[str] = set()
    todo = [top]
    while todo:
        here = todo.pop()
        real = os.path.realpath(here)
        if real in seen:
            continue
        seen.add(real)
        try:
            entries = sorted(os.scandir(here), key=lambda e: e.name)
        except OSError as exc:
            raise LogError(f"{here}: cannot list ({exc.strerror or exc})") from None
        for entry in entries:
            path = Path(entry.path)
            if entry.is_symlink():
                check_inside(run_dir, path)
            if entry.is_dir():
                todo.append(path)
            elif entry.is_file():
                out.append(path)
    return sorted(out)


def read_run_json(run_dir: str | Path) -> dict[str, Any]:
    """A run folder's ``run.json`` as an object; ``LogError`` naming the file when it is
    missing, not a regular file (a FIFO would block), a link out of the folder, not UTF-8,
    not JSON (the line, never the text) or not an object."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise LogError(f"{run_dir}: not a run folder (expected a folder with run.json)")
    path = run_dir / "run.json"
    if path.exists() and not path.is_file():
        raise LogError(f"{path}: not a regular file")
    if path.is_symlink():
        check_inside(run_dir, path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise LogError(f"{path}: missing (every run folder has a run.json)") from None
    except OSError as exc:
        raise LogError(f"{path}: cannot read ({exc.strerror or type(exc).__name__})") from None
    except UnicodeDecodeError as exc:
        raise LogError(f"{path}: not UTF-8 text (at byte offset {exc.start})") from None
    try:
        meta = json.loads(text)
    except json.JSONDecodeError as exc:  # its msg names the fault, never the text
        raise LogError(f"{path}: line {exc.lineno}: invalid JSON ({exc.msg})") from None
    except RecursionError:
        raise LogError(f"{path}: invalid JSON (nested too deeply)") from None
    if not isinstance(meta, dict):
        raise LogError(f"{path}: expected a JSON object at the top level")
    return meta


def samples_path(run_dir: str | Path, meta: dict[str, Any]) -> Path:
    """Where the run's samples are: ``run.json``'s ``samples``, inside the run folder."""
    return member(run_dir, meta.get("samples") or SAMPLES_DEFAULT, "run.json's samples")


def events_path(run_dir: str | Path, meta: dict[str, Any]) -> Path:
    """Where the run's events table is: ``run.json``'s ``events``, inside the run folder."""
    return member(run_dir, meta.get("events") or EVENTS_DEFAULT, "run.json's events")


def log_path(run_dir: str | Path) -> Path | None:
    """The run's ``run.log`` when it is a regular file inside the folder (a run recorded
    before run.log existed, or imported, has none: None)."""
    path = member(run_dir, LOG_NAME, "the run's log")
    return path if path.is_file() else None


def read_log_tail(run_dir: str | Path, max_bytes: int = 256 * 1024) -> str | None:
    """The last ``max_bytes`` of the run's ``run.log`` as text (bytes that are not UTF-8
    shown as U+FFFD; a first line cut in two dropped), or None when there is none."""
    path = log_path(run_dir)
    if path is None:
        return None
    try:
        with open(path, "rb") as fh:
            size = fh.seek(0, os.SEEK_END)
            fh.seek(max(0, size - max_bytes))
            data = fh.read(max_bytes)
    except OSError as exc:
        raise LogError(f"{path}: cannot read ({exc.strerror or exc})") from None
    text = data.decode("utf-8", errors="replace")
    if size > max_bytes:
        text = f"... (the first {size - len(data)} bytes are in the file)\n" + \
            text.split("\n", 1)[-1]
    return text
