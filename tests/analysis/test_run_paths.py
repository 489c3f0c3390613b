"""A run folder's run.json cannot make a reader open a file outside the folder, and an
unreadable file is named, never quoted."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pandas as pd
import pytest

from analysis.errors import LogError
from analysis.run_paths import files_under, member, read_run_json
from analysis.run_record import ColumnChunks, read_meta, read_run, sample_count

SECRET = "SECRET-hunter2-do-not-show"


def _run(folder: Path, **meta: object) -> Path:
    """A run folder of one part, its run.json holding ``meta``."""
    (folder / "samples.parquet").mkdir(parents=True)
    pd.DataFrame({"t_s": [0.0, 0.1], "thrust_n": [1.0, 2.0]}).to_parquet(
        folder / "samples.parquet" / "part-000000.parquet")
    (folder / "run.json").write_text(json.dumps({"id": folder.name, **meta}))
    return folder


OUTSIDE_THRUST_N = 31.4159265  # the outside file's thrust: in no message, were it read


@pytest.fixture
def outside(tmp_path: Path) -> Path:
    """Files beside the run folder that a run must not reach: a readable Parquet file,
    a folder of parts, and a text file with a secret."""
    out = tmp_path / "outside"
    (out / "parts").mkdir(parents=True)
    frame = pd.DataFrame({"t_s": [5.0], "thrust_n": [OUTSIDE_THRUST_N]})
    frame.to_parquet(out / "other.parquet")
    frame.to_parquet(out / "parts" / "part-000000.parquet")
    (out / "secret.csv").write_text(f"{SECRET},x\n1,2\n")
    (out / "secret.json").write_text(json.dumps({"id": "x", "key": SECRET}))
    return out


def _readers(run: Path) -> list[object]:
    return [lambda: read_run(run), lambda: ColumnChunks(run, ["thrust_n"]),
            lambda: sample_count(run)]


@pytest.mark.parametrize("name", ["{out}/other.parquet", "{out}/parts", "../outside/parts",
                                  "samples.parquet/../../outside/parts", "a\\b", "a\x00b",
                                  "x" * 300, ".", 7, ["samples.parquet"]])
def test_samples_named_outside_the_run_are_not_read(tmp_path: Path, outside: Path,
                                                    name: object) -> None:
    if isinstance(name, str):
        name = name.format(out=outside)
    run = _run(tmp_path / "run", samples=name)
    for read in _readers(run):
        with pytest.raises(LogError, match="is not a file name inside the run folder") as err:
            read()
        # one line, and nothing of the outside file's content (a path may hold any digits:
        # the test's own folder was once pytest-1499, which a check for "99" failed on)
        assert "\n" not in str(err.value) and f"{OUTSIDE_THRUST_N}" not in str(err.value)


def test_events_named_outside_are_not_read_nor_quoted(tmp_path: Path, outside: Path) -> None:
    for name in (str(outside / "secret.csv"), "../outside/secret.csv"):
        run = _run(tmp_path / f"run{len(name)}", events=name)
        with pytest.raises(LogError, match="not a file name inside the run folder") as err:
            read_run(run)
        assert SECRET not in str(err.value)


@pytest.mark.parametrize("link", ["samples.parquet", "samples.parquet/part-000001.parquet",
                                  "run.json", "events.csv"])
def test_links_inside_a_run_that_point_out_are_not_followed(tmp_path: Path, outside: Path,
                                                            link: str) -> None:
    run = _run(tmp_path / "run")
    target = {"samples.parquet": outside / "parts", "run.json": outside / "secret.json",
              "events.csv": outside / "secret.csv"}.get(link, outside / "other.parquet")
    if link == "samples.parquet":
        import shutil

        shutil.rmtree(run / link)
    else:
        (run / link).unlink(missing_ok=True)
    os.symlink(target, run / link)
    for read in _readers(run)[:1] if link == "events.csv" else _readers(run):
        with pytest.raises(LogError, match="a link to outside the run folder") as err:
            read()
        assert SECRET not in str(err.value)


def test_a_link_loop_in_a_samples_folder_ends(tmp_path: Path) -> None:
    run = _run(tmp_path / "run")
    os.symlink(run / "samples.parquet", run / "samples.parquet" / "again")
    assert [p.name for p in files_under(run, run / "samples.parquet")] == \
        ["part-000000.parquet"]
    assert len(read_run(run).samples) == 2


def test_links_that_stay_inside_are_followed(tmp_path: Path) -> None:
    run = _run(tmp_path / "run")
    (run / "samples.parquet").rename(run / "data")
    os.symlink("data", run / "samples.parquet")
    assert len(read_run(run).samples) == 2
    assert member(run, "samples.parquet", "samples") == run / "samples.parquet"


def test_a_files_content_is_never_quoted_in_an_error(tmp_path: Path) -> None:
    run = _run(tmp_path / "run")
    (run / "events.csv").write_text(f"{SECRET},{SECRET}\n1,2\n")
    with pytest.raises(LogError) as err:
        read_run(run)
    assert SECRET not in str(err.value) and "no columns t_s and kind" in str(err.value)
    (run / "events.csv").unlink()
    (run / "samples.parquet" / "part-000001.parquet").write_text(SECRET * 20)
    for read in _readers(run)[:2]:  # the count skips a damaged part
        with pytest.raises(LogError, match="not readable as Parquet") as err:
            read()
        assert SECRET not in str(err.value)
    (run / "run.json").write_text(f'{{"id": "{SECRET}", {SECRET}}}')
    with pytest.raises(LogError, match=r"line 1: invalid JSON") as err:
        read_meta(run)
    assert SECRET not in str(err.value)


@pytest.mark.parametrize("text", ["[1, 2]", '"a string"', "3", "null", "[" * 100_000])
def test_run_json_that_is_not_an_object_is_one_line(tmp_path: Path, text: str) -> None:
    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_text(text)
    with pytest.raises(LogError, match=r"run\.json: ") as err:
        read_run_json(run)
    assert "\n" not in str(err.value)


def test_a_run_json_that_is_not_utf8_is_named_by_offset_not_by_byte(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_bytes(b'{"id": "\xab\xcd"}')
    with pytest.raises(LogError, match=r"not UTF-8 text \(at byte offset 8\)$") as err:
        read_run_json(run)
    assert "0xab" not in str(err.value) and "\\xab" not in str(err.value)
