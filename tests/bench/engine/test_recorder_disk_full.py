"""A full disk during a step (ENOSPC on a samples part): the motor stops safely, the run
is recorded as aborted, the partial run stays readable and the command says where it is
in one line with exit code 2, no traceback."""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import pytest

import bench.engine.recorder as recorder_module
from analysis.run_record import read_run
from bench.cli import main
from bench.engine.recorder import RunRecorder
from bench.errors import RecordingError


@pytest.fixture
def disk_fills_after(monkeypatch):
    """``fill(n)``: the recorder's (n+1)-th samples part write raises ENOSPC, and so does
    every later one (a full disk stays full)."""
    real = recorder_module.pq.write_table

    def fill(parts_ok: int) -> None:
        count = {"files": 0}

        def write_table(table, where, *args, **kwargs):
            if isinstance(where, str | os.PathLike):
                count["files"] += 1
                if count["files"] > parts_ok:
                    # pyarrow has created the file before the disk filled up
                    Path(where).write_bytes(b"PAR1 half")
                    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(where))
            return real(table, where, *args, **kwargs)

        monkeypatch.setattr(recorder_module.pq, "write_table", write_table)

    return fill


def test_disk_full_during_a_step(sim_rig_mapped_path: Path, tmp_path: Path, capsys,
                                 disk_fills_after) -> None:
    out = tmp_path / "runs"
    disk_fills_after(2)  # parts of 10 s of rig time (written behind the simulated run):
    code = main(["step", "--rig", str(sim_rig_mapped_path), "--repeats", "50", "--out",
                 str(out)])  # the third fails at 30 s, said when the fourth is handed over
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    (run_dir,) = out.glob("*-step1")
    meta = json.loads((run_dir / "run.json").read_text())
    assert meta["status"] == "abort"
    assert "No space left on device" in meta["reason"] and meta["rows_lost"] > 0
    assert err.strip() == (
        f"rotorbench: error: run aborted: cannot write samples to "
        f"{run_dir / 'samples.parquet'} (No space left on device); ESC idle and disarmed; "
        f"the partial run is in {run_dir} (status abort, {meta['rows']} rows readable)")
    # the partial run reads back: the two parts written, no half-written temporary
    rec = read_run(run_dir)
    assert meta["parts"] == 2 and len(rec.samples) == meta["rows"] > 0
    assert not list((run_dir / "samples.parquet").glob(".*"))
    # the motor was stopped safely and that is on record
    kinds = rec.events["kind"].tolist()
    assert kinds[-2:] == ["safe_stop", "run_end"]
    assert rec.events["label"].iloc[-1] == "abort"
    # the index agrees
    assert main(["runs", "--out", str(out)]) == 0
    assert "abort" in capsys.readouterr().out


def test_last_flush_failing_turns_a_complete_run_into_an_abort(tmp_path: Path,
                                                                disk_fills_after) -> None:
    import numpy as np

    rec = RunRecorder(tmp_path / "r", {"kind": "x"})
    rows = {c: np.linspace(0.0, 0.5, 6) for c in recorder_module.BASE_COLUMNS}
    rec.append(rows)
    disk_fills_after(0)
    with pytest.raises(RecordingError, match="No space left on device"):
        rec.finish("success", "sequence complete")
    meta = json.loads((tmp_path / "r" / "run.json").read_text())
    assert meta["status"] == "abort" and meta["rows_lost"] == 6 and meta["rows"] == 0
    assert rec.finish("success", "again") is rec.meta  # idempotent, no second raise


def test_write_behind_reports_a_failed_part_when_the_next_one_is_handed_over(
        tmp_path: Path, disk_fills_after) -> None:
    """In the background a failed part cannot raise where it was handed over: the next
    part (or ``finish``) raises it, and its rows count as lost."""
    import numpy as np

    rec = RunRecorder(tmp_path / "r", {"kind": "x"})
    rec.write_behind(part_s=1.0)
    disk_fills_after(1)

    def rows(t0: float) -> dict:
        return {c: t0 + np.arange(500) / 1000.0 for c in recorder_module.BASE_COLUMNS}

    for t0 in (0.0, 0.5, 1.0, 1.5, 2.0, 2.5):  # parts 0 (written) and 1 (fails) handed over
        rec.append(rows(t0))
    with pytest.raises(RecordingError, match="No space left on device"):
        rec.append(rows(3.0))  # hands part 2 over: part 1's failure comes out here
    meta = rec.finish("abort", "recording failed")
    assert (meta["parts"], meta["rows"], meta["rows_lost"]) == (1, 1000, 2500)
    assert meta["status"] == "abort" and "No space left" in meta["recording_error"]
    assert not list((tmp_path / "r" / "samples.parquet").glob(".*"))
