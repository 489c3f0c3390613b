"""Files and folders the commands write follow the user's umask, and a file they replace
keeps its mode (with umask 022 they were 0600/0700, and a sweep turned
the user's 0644 thrust map into 0600)."""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path

import pytest

from bench.cli import main
from tests.conftest import SIZINGLAB


def mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


@pytest.fixture
def umask_022() -> Iterator[None]:
    old = os.umask(0o022)
    try:
        yield
    finally:
        os.umask(old)


def test_write_atomically_follows_the_umask_and_keeps_a_mode(tmp_path: Path,
                                                             umask_022: None) -> None:
    from analysis.atomic_files import temp_beside, write_atomically

    f = tmp_path / "a.txt"
    write_atomically(f, lambda tmp: tmp.write_text("1"))
    assert mode(f) == 0o644
    f.chmod(0o640)
    write_atomically(f, lambda tmp: tmp.write_text("2"))
    assert mode(f) == 0o640 and f.read_text() == "2"
    assert mode(temp_beside(tmp_path / "d", folder=True)) == 0o755
    os.umask(0o077)
    write_atomically(tmp_path / "b.txt", lambda tmp: tmp.write_text("1"))
    assert mode(tmp_path / "b.txt") == 0o600  # a strict umask is obeyed too
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".a.txt")] == []


def test_sweep_keeps_the_thrust_map_mode_and_writes_rig_copies_0644(
        tmp_path: Path, umask_022: None, sim_rig_path: Path, capsys) -> None:
    out = tmp_path / "runs"
    assert main(["sweep", "--rig", str(sim_rig_path), "--out", str(out)]) == 0
    tmap = sim_rig_path.with_name("sim.thrust_map.csv")
    assert mode(tmap) == 0o644 and mode(sim_rig_path) == 0o644
    tmap.chmod(0o640)  # the user's choice
    assert main(["sweep", "--rig", str(sim_rig_path), "--out", str(out)]) == 0
    assert mode(tmap) == 0o640
    # the shipped (read-only) rig: its copy with the map goes under <out>/rigs
    assert main(["sweep", "--out", str(out)]) == 0
    copies = sorted((out / "rigs").iterdir())
    assert copies and all(mode(p) == 0o644 for p in copies), [(p, oct(mode(p))) for p in copies]


def test_calibration_outputs_are_0644(tmp_path: Path, umask_022: None, capsys) -> None:
    log, cal, fixed = tmp_path / "sim.csv", tmp_path / "cal.json", tmp_path / "fixed.parquet"
    assert main(["calibrate", "--simulate-log", str(log), "--short"]) == 0
    assert main(["calibrate", "--from-log", str(log), "--out", str(cal)]) == 0
    assert main(["calibrate", "apply", "--cal", str(cal), str(log), "--out", str(fixed)]) == 0
    assert [oct(mode(p)) for p in (log, cal, fixed)] == ["0o644"] * 3


def test_attitude_out_is_0644(tmp_path: Path, umask_022: None, capsys) -> None:
    log = tmp_path / "imu.csv"
    rows = [f"{i / 100:.2f},0.01,0,0,0,0,9.81" for i in range(200)]
    log.write_text("t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,acc_x_m_s2,acc_y_m_s2,"
                   "acc_z_m_s2\n" + "\n".join(rows) + "\n")
    out = tmp_path / "att.csv"
    assert main(["attitude", str(log), "--out", str(out)]) == 0
    assert mode(out) == 0o644


@pytest.mark.slow
def test_demo_folder_is_0755(tmp_path: Path, umask_022: None, capsys) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--combos", "1", "--repeats", "1", "--out", str(out)]) == 0
    assert mode(out) == 0o755
    assert mode(out / "demo.json") == 0o644


def test_imported_catalog_folder_is_0755(tmp_path: Path, umask_022: None, capsys,
                                         shared_data: Path) -> None:
    out = tmp_path / "cat"
    assert main(["import-sizinglab", "--source", str(SIZINGLAB),
                 "--out", str(out)]) == 0
    assert mode(out) == 0o755
