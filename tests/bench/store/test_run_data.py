"""Nothing a run folder, a spool or a catalog row says can make the lab store read or write
outside its places: run ids are checked where they enter, a run's files stay inside its
folder, a catalog row's data location is the store's own. Real services: PostgreSQL and
moto's S3 server (tests/services.py), and a shared-folder data location."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import psycopg
import pytest

from bench.cli import main
from bench.errors import RigError
from bench.store.run_data import DataLocation, row_location

HOSTILE_IDS = ["../../escape", "../escape", "/tmp/escape", "a/../../escape", "..\\..\\escape",
               "a\x00b", "x" * 300, ".", "..", ""]
SECRET = "SECRET-hunter2-do-not-show"


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small imported run folder (its id is its folder's name)."""
    root = tmp_path_factory.mktemp("imported")
    log = root / "stand.csv"
    log.write_text("t_s,throttle_us,thrust_n\n0,1000,0\n0.1,1100,0.5\n0.2,1200,1\n")
    assert main(["import", str(log), "--format", "csv", "--out", str(root / "good-run")]) == 0
    return root / "good-run"


def _copy(run: Path, where: Path, **meta: object) -> Path:
    """A copy of ``run`` at ``where`` whose run.json has ``meta`` on top."""
    shutil.copytree(run, where)
    old = json.loads((run / "run.json").read_text())
    (where / "run.json").write_text(json.dumps({**old, **meta}))
    return where


def _tree(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def _keys(location: DataLocation) -> list[str]:
    import pyarrow.fs as pafs

    fs, root = location._fs()
    bucket = root.split("/", 1)[0]
    return [i.path for i in fs.get_file_info(pafs.FileSelector(bucket, recursive=True))]


@pytest.fixture(params=["folder", "s3"])
def location(request: pytest.FixtureRequest, tmp_path: Path) -> DataLocation:
    if request.param == "folder":
        return DataLocation(str(tmp_path / "lab" / "data" / "runs"))
    s3 = request.getfixturevalue("s3_env")
    return DataLocation(f"s3://{s3.bucket}/runs")


@pytest.mark.parametrize("bad", HOSTILE_IDS)
def test_a_run_id_that_is_not_one_reads_and_writes_nothing(run: Path, tmp_path: Path,
                                                           location: DataLocation,
                                                           bad: str) -> None:
    before = _tree(tmp_path)
    for call in (lambda: location.upload(run, bad), lambda: location.run_uri(bad),
                 lambda: location.has_run(bad),
                 lambda: location.put_files(run, bad, ["run.json"]),
                 lambda: location.download(bad, tmp_path / "cache")):
        with pytest.raises(RigError, match="is not a run id"):
            call()
    assert _tree(tmp_path) == before
    if location.is_s3:
        assert _keys(location) == []


def test_a_link_in_a_run_folder_that_points_out_is_not_uploaded(run: Path, tmp_path: Path,
                                                                location: DataLocation) -> None:
    secret = tmp_path / "secret.txt"
    secret.write_text(SECRET)
    folder = _copy(run, tmp_path / "spool" / run.name)
    os.symlink(secret, folder / "notes.txt")
    with pytest.raises(RigError, match="a link to outside the run folder") as err:
        location.upload(folder, run.name)
    assert SECRET not in str(err.value)
    with pytest.raises(RigError, match="not a file name inside the run folder"):
        location.put_files(folder, run.name, ["../secret.txt"])
    assert not location.has_run(run.name)
    if location.is_s3:
        assert _keys(location) == []
    else:
        assert not Path(location.uri).exists() or not any(Path(location.uri).rglob("*.txt"))


def test_a_whole_run_goes_up_and_comes_back(run: Path, tmp_path: Path,
                                           location: DataLocation) -> None:
    location.upload(run, run.name)
    back = location.download(run.name, tmp_path / "cache")
    assert back == tmp_path / "cache" / run.name
    assert _tree(back) == _tree(run)


def test_a_downloaded_key_that_would_leave_the_cache_is_refused(run: Path, tmp_path: Path,
                                                                s3_env: object) -> None:
    """A bucket holding ``runs/<id>/../../escape``: S3 keeps such a key as it is (written
    with boto3, which does not normalise it), and pyarrow lists it under the run."""
    import boto3

    location = DataLocation(f"s3://{s3_env.bucket}/runs")
    location.upload(run, run.name)
    boto3.client("s3", endpoint_url=s3_env.endpoint).put_object(
        Bucket=s3_env.bucket, Key=f"runs/{run.name}/../../escape", Body=SECRET.encode())
    assert any(k.endswith(f"{run.name}/../../escape") for k in _keys(location))
    cache = tmp_path / "cache"
    with pytest.raises(RigError, match="not downloaded") as err:
        location.download(run.name, cache)
    assert SECRET not in str(err.value)
    assert not list(tmp_path.rglob("escape")) and list(cache.iterdir()) == []


def test_a_shared_folder_run_with_a_link_out_is_not_downloaded(run: Path,
                                                               tmp_path: Path) -> None:
    location = DataLocation(str(tmp_path / "shared"))
    location.upload(run, run.name)
    (tmp_path / "secret.txt").write_text(SECRET)
    os.symlink(tmp_path / "secret.txt", tmp_path / "shared" / run.name / "notes.txt")
    with pytest.raises(RigError, match="a link to outside the run folder"):
        location.download(run.name, tmp_path / "cache")
    assert list((tmp_path / "cache").iterdir()) == []


@pytest.mark.parametrize("data", ["{other}/{id}", "s3://other-bucket/runs/{id}",
                                  "file://{other}/{id}", "{loc}/{id}/../../x", "{loc}/x",
                                  "{loc}"])
def test_a_row_may_name_only_this_locations_own_uri(tmp_path: Path, data: str) -> None:
    location = DataLocation(str(tmp_path / "data"))
    text = data.format(other=tmp_path / "other", id="r1", loc=location.uri)
    with pytest.raises(RigError, match=r"^run r1: its catalog row names its data at .*not read"):
        location.for_row("r1", text)
    assert location.for_row("r1", f"{location.uri}/r1") is location
    assert location.for_row("r1", "") is location


@pytest.mark.parametrize("data", ["", "s3://bucket/runs/other", "s3://bucket/runs/r1/../x",
                                  "r1", "/r1/..", "s3://bucket/runs/../../r2"])
def test_without_a_store_location_a_row_must_name_its_own_run(data: str) -> None:
    """A lab that saved no data location (benches give --out) has only the row to go by:
    it must end in the run's id, and the download is checked as always."""
    with pytest.raises(RigError, match=r"^run r1: its catalog row names no data location"):
        row_location("r1", data, None)
    assert row_location("r1", "s3://bucket/runs/r1", None) == DataLocation("s3://bucket/runs")
    with pytest.raises(RigError, match="is not a run id"):
        row_location("../r1", "s3://bucket/runs/../r1", None)


# -- the commands over PostgreSQL + S3 ----------------------------------------------------


def _lab(pg_url: str, data: str) -> None:
    assert main(["store", "init", pg_url, "--data", data]) == 0


def _catalog_ids(pg_url: str) -> list[str]:
    with psycopg.connect(pg_url) as con:
        return sorted(r[0] for r in con.execute("SELECT run_id FROM runs"))


@pytest.mark.parametrize("where", ["folder", "s3"])
def test_store_sync_delivers_good_runs_and_refuses_hostile_ids(
        run: Path, tmp_path: Path, pg_url: str, where: str, request: pytest.FixtureRequest,
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    if where == "s3":
        data = f"s3://{request.getfixturevalue('s3_env').bucket}/runs"
    else:
        data = str(tmp_path / "lab" / "runs")
    _lab(pg_url, data)
    spool = tmp_path / "spool"
    _copy(run, spool / run.name)
    for i, bad in enumerate(HOSTILE_IDS[:6]):
        _copy(run, spool / f"bad{i}", id=bad)
    before = _tree(tmp_path)
    capsys.readouterr()
    code = main(["store", "sync", "--store", pg_url, "--spool", str(spool)])
    out, err = capsys.readouterr()
    assert code == 2 and "Traceback" not in out + err
    assert (out + err).count("is not a run id") == 6, out + err
    assert _catalog_ids(pg_url) == [run.name]
    assert not list(tmp_path.rglob("escape*"))
    new = _tree(tmp_path) - before
    inside = "lab/runs/" if where == "folder" else "spool/"
    assert all(p.startswith((inside, "lab")) or p.endswith(".published") for p in new), new
    if where == "s3":
        top = data.removeprefix("s3://")
        keys = _keys(DataLocation(data))
        assert all(k == top or k.startswith(f"{top}/{run.name}") for k in keys), keys


def test_store_push_refuses_hostile_ids(run: Path, tmp_path: Path, pg_url: str,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    data = tmp_path / "lab" / "runs"
    _lab(pg_url, str(data))
    laptop = tmp_path / "laptop"
    _copy(run, laptop / run.name)
    for i, bad in enumerate(HOSTILE_IDS[:6]):
        _copy(run, laptop / f"bad{i}", id=bad)
    capsys.readouterr()
    code = main(["store", "push", str(laptop), "--store", pg_url])
    out, err = capsys.readouterr()
    assert code == 2 and "Traceback" not in out + err, out + err
    assert _catalog_ids(pg_url) == [run.name]
    assert not list(tmp_path.rglob("escape*"))
    assert {p.name for p in data.iterdir()} == {run.name}


def _insert_row(pg_url: str, run_id: str, data: str, status: str = "success") -> None:
    """A row as another bench (or anyone with the superuser's login) could write it."""
    with psycopg.connect(pg_url) as con:
        con.execute("INSERT INTO runs (run_id, bench, operator, status, data, started_utc) "
                    "VALUES (%s, 'hostile', 'x', %s, %s, now())", (run_id, status, data))


def test_a_hostile_catalog_row_cannot_make_run_folder_read_or_write_outside(
        run: Path, tmp_path: Path, pg_url: str, s3_env: object,
        monkeypatch: pytest.MonkeyPatch) -> None:
    from bench.store.stores import open_store

    data = f"s3://{s3_env.bucket}/runs"
    _lab(pg_url, data)
    cache = tmp_path / "cache"
    monkeypatch.setenv("XDG_CACHE_HOME", str(cache))
    other = _copy(run, tmp_path / "elsewhere" / "r-other",
                  operator=SECRET)  # a run folder outside the store
    store = open_store(pg_url, spool=tmp_path / "spool")
    _insert_row(pg_url, run.name, DataLocation(data).upload(run, run.name))
    _insert_row(pg_url, "r-other", str(other))
    _insert_row(pg_url, "r-file", f"file://{other}")
    _insert_row(pg_url, "r-bucket", f"s3://{s3_env.bucket}/elsewhere/r-bucket")
    for bad in ("../../escape", "../rotorbench/escape", "a\\b"):
        _insert_row(pg_url, bad, f"{data}/{bad}")
    before = _tree(tmp_path)
    for rid in ("r-other", "r-file", "r-bucket"):
        with pytest.raises(RigError, match="not in the store's data location") as err:
            store.run_folder(rid)
        assert SECRET not in str(err.value)
    for bad in ("../../escape", "../rotorbench/escape", "a\\b"):
        with pytest.raises(RigError, match="is not a run id"):
            store.run_folder(bad)
    assert _tree(tmp_path) == before
    assert store.run_folder(run.name) == cache / "rotorbench" / "runs" / run.name
