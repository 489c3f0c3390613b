"""Where the lab keeps run folders: a local or shared folder, or ``s3://bucket/prefix``.

pyarrow's file systems do the work (``pyarrow.fs.S3FileSystem`` reads the standard
``AWS_*`` variables, ``AWS_ENDPOINT_URL`` included, so MinIO, Ceph or moto work as AWS
does). A run folder is copied whole (``run.json``, ``events.csv``, ``samples.parquet/``
parts) under ``<location>/<run id>/``; ``run.json`` goes last, so a run whose upload
broke off has no ``run.json`` there and is uploaded again by ``store sync``.

Run ids and file names come from run folders and catalog rows other people write, so
every one is checked before a path or key is built from it: the run id by
``bench.engine.run_ids.check_run_id``, a file of the run by ``analysis.run_paths`` (inside
the run folder, links followed), a downloaded key to stay inside the cache's run folder.
A catalog row's ``data`` is used only when it is the store's own URI of that run
(``row_location``); a lab that saved no data location trusts its rows to name it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from analysis.errors import LogError
from analysis.run_paths import files_under, member
from bench.engine.run_ids import check_run_id
from bench.errors import RigError

__all__ = ["DataLocation", "DataUnavailable", "refuse_credentials", "row_location"]


class DataUnavailable(RigError):
    """The object store or shared folder could not be reached: a bench spools instead."""


@dataclass(frozen=True)
class DataLocation:
    """``uri``: a folder path or ``s3://bucket/prefix``."""

    uri: str

    def __post_init__(self) -> None:
        refuse_credentials(self.uri)

    @property
    def is_s3(self) -> bool:
        return self.uri.startswith("s3://")

    def _fs(self) -> tuple[Any, str]:
        import pyarrow.fs as pafs

        if self.is_s3:
            try:
                fs, root = _s3_from_uri(self.uri)
            except (OSError, ValueError) as exc:
                raise DataUnavailable(f"data location {self.uri}: {exc}") from None
            return fs, root.rstrip("/")
        return pafs.LocalFileSystem(), str(Path(self.uri).expanduser().resolve())

    def run_uri(self, run_id: str) -> str:
        """``<location>/<run id>`` (``RigError`` for a string that is not a run id)."""
        return f"{self.uri.rstrip('/')}/{check_run_id(run_id, 'data location: run')}"

    def for_row(self, run_id: str, data: str | None) -> DataLocation:
        """This location, for a catalog row of run ``run_id`` whose ``data`` names where it
        is: a row may name only this location's own URI of that run (or nothing); any
        other place (another bucket, a folder, ``file://``) is refused, not read."""
        uri = self.run_uri(run_id)
        if data and data.rstrip("/") != uri:
            from analysis.errors import excerpt

            raise RigError(f"run {run_id}: its catalog row names its data at "
                           f"{excerpt(data, 120)}, not in the store's data location "
                           f"{self.uri}; not read")
        return self

    def upload(self, run_dir: Path, run_id: str, *, done: set[str] | None = None,
               threads: int = 8) -> str:
        """Copy ``run_dir`` to ``<location>/<run_id>``: the files not in ``done`` (relative
        paths already uploaded, e.g. by ``TrailingUpload`` during the run) in parallel,
        then ``run.json`` last; returns the run's data URI. Raises ``DataUnavailable``
        when the store fails."""
        check_run_id(run_id, f"{run_dir}: run")
        try:
            files = [p for p in files_under(run_dir) if not p.name.startswith(".")]
        except LogError as exc:
            raise RigError(str(exc)) from None
        rels = [p.relative_to(run_dir).as_posix() for p in files]
        todo = [r for r in rels if r != "run.json" and r not in (done or set())]
        self.put_files(run_dir, run_id, todo, threads=threads)
        if "run.json" in rels:  # the seal: a run without it is not whole
            self.put_files(run_dir, run_id, ["run.json"], threads=1)
        return self.run_uri(run_id)

    def put_files(self, run_dir: Path, run_id: str, rels: list[str], threads: int = 8) -> None:
        """Upload ``rels`` (paths relative to ``run_dir``) under ``<location>/<run_id>/``."""
        import shutil
        from concurrent.futures import ThreadPoolExecutor

        check_run_id(run_id, f"{run_dir}: run")
        if not rels:
            return
        try:
            for rel in rels:  # each a file inside the run folder, links followed
                member(run_dir, rel, "file")
        except LogError as exc:
            raise RigError(str(exc)) from None
        fs, root = self._fs()
        dest = f"{root}/{run_id}"

        def put(rel: str) -> None:
            # closed here, so a failed PUT raises (pyarrow's copy_files would drop the
            # error of a delayed open when it destroys the stream: a run marked published
            # that is not in the store)
            with open(Path(run_dir) / rel, "rb") as src, \
                    fs.open_output_stream(f"{dest}/{rel}") as out:
                shutil.copyfileobj(src, out, 1 << 20)

        try:
            if not self.is_s3:  # a folder needs its folders; S3 keys do not
                for sub in sorted({f"{dest}/{r.rsplit('/', 1)[0]}" if "/" in r else dest
                                   for r in rels}):
                    fs.create_dir(sub, recursive=True)
            with ThreadPoolExecutor(max_workers=max(1, min(threads, len(rels)))) as pool:
                list(pool.map(put, rels))
        except OSError as exc:
            raise DataUnavailable(f"data location {self.uri}: upload of {run_id} failed "
                                  f"({_short(exc)})") from None

    def has_run(self, run_id: str) -> bool:
        """True when ``<location>/<run_id>/run.json`` exists (a whole upload)."""
        import pyarrow.fs as pafs

        check_run_id(run_id, "data location: run")
        fs, root = self._fs()
        try:
            info = fs.get_file_info(f"{root}/{run_id}/run.json")
        except OSError as exc:
            raise DataUnavailable(f"data location {self.uri}: {_short(exc)}") from None
        return info.type == pafs.FileType.File

    def download(self, run_id: str, dest: Path) -> Path:
        """Copy ``<location>/<run_id>`` into ``dest/<run_id>`` (a cache) and return it.
        Every file lands inside that folder: a key or a shared folder's link that would
        leave it is refused, and nothing of the run is kept."""
        import shutil

        check_run_id(run_id, "data location: run")
        fs, root = self._fs()
        target = Path(dest) / run_id
        if (target / "run.json").exists():
            return target
        tmp = Path(dest) / f".{run_id}.part"
        try:
            shutil.rmtree(tmp, ignore_errors=True)  # a download that broke off
            tmp.mkdir(parents=True)
            for rel in self._files_of(fs, f"{root}/{run_id}"):
                out = member(tmp, rel, "object")
                out.parent.mkdir(parents=True, exist_ok=True)
                with fs.open_input_stream(f"{root}/{run_id}/{rel}") as src, \
                        open(out, "xb") as sink:
                    shutil.copyfileobj(src, sink, 1 << 20)
            tmp.rename(target)
        except LogError as exc:
            shutil.rmtree(tmp, ignore_errors=True)
            raise RigError(f"data location {self.uri}: run {run_id} not downloaded: "
                           f"{exc}") from None
        except OSError as exc:
            shutil.rmtree(tmp, ignore_errors=True)
            raise DataUnavailable(f"data location {self.uri}: download of {run_id} failed "
                                  f"({_short(exc)})") from None
        return target

    def _files_of(self, fs: Any, base: str) -> list[str]:
        """The run's files as paths relative to ``base``; in a folder location, a link
        that leaves the run's folder is refused (``LogError``)."""
        import pyarrow.fs as pafs

        if not self.is_s3:
            if not Path(base).is_dir():
                raise FileNotFoundError(f"{base}: no such folder")
            return [p.relative_to(base).as_posix() for p in files_under(base)]
        infos = fs.get_file_info(pafs.FileSelector(base, recursive=True))
        return sorted(i.path[len(base) + 1:] for i in infos
                      if i.type == pafs.FileType.File)


def row_location(run_id: str, data: str | None, store: DataLocation | None) -> DataLocation:
    """Where to fetch run ``run_id`` whose catalog row says ``data``: the store's own data
    location (``DataLocation.for_row``: a row naming another place is refused). A store
    without one (none saved by ``store init --data``, no ``--out``) has only the row to
    go by: its ``data`` must end in ``/<run id>``, and the download stays in the cache."""
    if store is not None:
        return store.for_row(run_id, data)
    check_run_id(run_id, "catalog row: run")
    base, _, last = (data or "").rstrip("/").rpartition("/")
    if not base or last != run_id:
        from analysis.errors import excerpt

        raise RigError(f"run {run_id}: its catalog row names no data location for it "
                       f"({excerpt(data or '', 120)}) and the store has none; give --out "
                       "LOCATION or save one with `rotorbench store init URL --data LOCATION`")
    return DataLocation(base)


_CREDENTIAL_KEYS = ("access_key", "secret_key", "session_token")


def refuse_credentials(uri: str) -> None:
    """A data location is printed and stored in every catalog row, which readers see: a
    key in it (``s3://KEY:SECRET@bucket``, ``?secret_key=``) is refused without echoing it."""
    if "://" not in uri:
        return
    from urllib.parse import parse_qsl, urlsplit

    scheme = uri.split("://", 1)[0]
    query = uri.split("?", 1)[1] if "?" in uri else ""
    if "@" in uri or any(k.lower() in _CREDENTIAL_KEYS for k, _ in parse_qsl(query)) or \
            urlsplit(uri.split("?", 1)[0]).password is not None:
        raise RigError(f"data location {scheme}://…: holds credentials, which would be "
                       "printed and stored in the catalog for every reader; give them in "
                       "AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY (or ~/.aws/credentials)")


def _s3_from_uri(uri: str) -> tuple[Any, str]:
    """pyarrow's S3 file system for ``uri`` with ``allow_delayed_open``: a file smaller
    than a multipart part then goes up in one PUT, not in the three requests (create,
    part, complete) pyarrow makes by default. A run folder is dozens to hundreds of such
    files, and each request costs both sides milliseconds of CPU whatever its size: the
    three requests per file were half of the object store's time for a 200-repeat Step 1
    (docs/lab.md, Speed). A failed PUT is raised when the file is closed
    (``DataLocation.put_files``). A pyarrow without the option gets the URI as it is."""
    import pyarrow.fs as pafs

    if "allow_delayed_open=" in uri:
        return pafs.FileSystem.from_uri(uri)
    try:
        return pafs.FileSystem.from_uri(f"{uri}{'&' if '?' in uri else '?'}"
                                        "allow_delayed_open=true")
    except ValueError as exc:
        if "allow_delayed_open" not in str(exc):
            raise
        return pafs.FileSystem.from_uri(uri)


def _short(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0][:300] if text else type(exc).__name__
