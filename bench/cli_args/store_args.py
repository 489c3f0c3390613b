"""Where runs and constants live (``--store``, ``--out``; bench/store, docs/lab.md): the
options, the store they name, a RUN argument, the publish after a recording command.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bench.cli_args.option_values import given_options
from optimizer.errors import RequestError

__all__ = ["DEFAULT_OUT", "DEFAULT_RUNS_ROOT", "add_store_args", "data_location_text",
           "named_store", "publish_runs", "recording_store", "run_folder_arg", "store_from_args"]

#: The output root of every command's runs and runs.sqlite (``--out``).
DEFAULT_OUT = Path("runs")
#: The same root, named for the sizing commands that read the constants store in it.
DEFAULT_RUNS_ROOT = DEFAULT_OUT


def add_store_args(p: argparse.ArgumentParser, *, records: bool = False) -> None:
    """``--store`` (a folder or the lab catalog); recording commands also get ``--spool``
    and ``--bench``."""
    p.add_argument("--store", metavar="DIR|URL", default=None,
                   help="where runs and constants live: a folder (default: --out, or "
                        "$ROTORBENCH_STORE) or the lab catalog postgresql://user@host/db "
                        "(docs/lab.md)")
    if records:
        p.add_argument("--spool", type=Path, default=None,
                       help="lab catalog: where runs are recorded first, on this machine "
                            "(default ~/.local/share/rotorbench/spool)")
        p.add_argument("--bench", default=None,
                       help="this bench's name in the lab catalog (default: the rig file's "
                            "name, else the host name)")


def data_location_text(value: str | os.PathLike[str]) -> str:
    """``--out`` as a data location: ``s3://bucket/prefix`` survives being a ``Path``
    (which folds ``//``) or a folder path."""
    text = os.fspath(value)
    if text.startswith("s3:/") and not text.startswith("s3://"):
        return "s3://" + text[len("s3:/"):]
    return text


def named_store(args: argparse.Namespace) -> str | None:
    """The store the user named, ``--store`` or ``$ROTORBENCH_STORE``; None when the
    command falls back to the folder ``--out``."""
    from bench.store.store_url import STORE_ENV

    return getattr(args, "store", None) or os.environ.get(STORE_ENV) or None


def store_from_args(args: argparse.Namespace, *, records: bool = False,
                    out_attr: str = "out") -> Any:
    """The store of a command: ``--store`` or ``$ROTORBENCH_STORE``, else the folder
    ``--out``. With the lab catalog, ``--out`` names the data location (``s3://...`` or a
    shared folder) and a recording command records into the spool: ``args.out`` becomes
    the spool, so everything the command writes beside its runs stays on this machine.
    ``out_attr`` names the run-root option where it is not ``--out`` (calibrate's
    ``--runs``)."""
    from bench.store.store_url import parse_store
    from bench.store.stores import FolderStore, open_store

    text = named_store(args)
    flag = "--" + out_attr.replace("_", "-")
    out = getattr(args, out_attr, None)
    if not text:
        if out is not None and data_location_text(out).startswith("s3://"):
            raise RequestError(f"{flag} {data_location_text(out)}: an object store holds the "
                               "lab catalog's runs; give the catalog with --store "
                               "postgresql://... (docs/lab.md)")
        return FolderStore(Path(out if out is not None else DEFAULT_RUNS_ROOT))
    url = parse_store(text)
    if url.folder is not None:
        if out is not None and given_options(args, flag) and \
                Path(out).resolve() != url.folder.resolve():
            raise RequestError(f"{flag} {out} and --store {url.folder} name two folder "
                               "stores; give one")
        if out is not None:
            setattr(args, out_attr, url.folder)
        return FolderStore(url.folder)
    data = data_location_text(out) if out is not None and given_options(args, flag) \
        else None
    store = open_store(text, data=data, spool=getattr(args, "spool", None))
    if records:
        setattr(args, out_attr, store.record_root())
    return store


def recording_store(args: argparse.Namespace, out_attr: str = "out", *,
                    warn: Callable[[str], None]) -> Any:
    """The store a recording command writes to, checked before anything spins (a
    reader-only lab login is refused here); ``--bench`` names the bench in run.json.
    ``warn`` (the command's stderr) hears of runs left in a lab spool at exit."""
    store = store_from_args(args, records=True, out_attr=out_attr)
    if hasattr(store, "exit_notice"):
        store.exit_notice = warn
    if getattr(args, "bench", None):
        os.environ["ROTORBENCH_BENCH"] = str(args.bench)
    if not getattr(args, "dry_run", False):
        store.check_can_record()
    return store


def publish_runs(store: Any, run_dir: Path | None = None, *,
                 tell: Callable[[str], None]) -> None:
    """After a recording command: the lab store publishes what the spool holds (this run,
    a map sweep before it) and says through ``tell`` (the command's output) where each
    went, or that it waits for ``store sync``."""
    note = store.after_run(run_dir)
    if note:
        tell(note)


def run_folder_arg(args: argparse.Namespace, value: str | os.PathLike[str]) -> Path:
    """A RUN argument: a run folder, or a run id of ``--store``/``$ROTORBENCH_STORE``
    (a lab run is fetched into the local cache)."""
    path = Path(value)
    if path.exists() or not named_store(args):
        return path
    return Path(store_from_args(args).run_folder(str(value)))
