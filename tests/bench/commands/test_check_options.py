"""`rotorbench check` on rigs and options it cannot use: mixed sim and hardware, a replay
file that is no recording, a --save checked before the listening."""

from __future__ import annotations

from pathlib import Path

from tests.conftest import RIGS, run_bad


def test_check_rig_mixing_sim_and_hardware(tmp_path: Path, capsys, fixtures_dir: Path) -> None:
    """check listed each sim device as FAIL 'unknown device URL scheme 'sim''; step said
    what is wrong. Both now say it in one line."""
    text = (RIGS / "sim.toml").read_text()
    rig = tmp_path / "mixed.toml"
    rig.write_text(text.replace('url = "sim://power"', 'url = "nidaq://Dev1/ai1,ai2"'))
    (tmp_path / "sim.thrust_map.csv").write_text(
        (RIGS / "sim.thrust_map.csv").read_text())
    for argv in (["check"], ["step", "--repeats", "1", "--out", str(tmp_path / "runs")]):
        err = run_bad(capsys, *argv, "--rig", str(rig))
        assert "[devices.esc] url 'sim://esc': sim:// devices run on the simulated clock" in err


def test_replay_file_that_is_not_a_recording(tmp_path: Path, capsys, fixtures_dir: Path) -> None:
    """Garbage bytes said 'This file contains pickled (object) data ... allow_pickle='."""
    text = (RIGS / "sim.toml").read_text()
    rec = tmp_path / "rec.npz"
    rec.write_bytes(b"\xac\x00 garbage" * 20)
    rig = tmp_path / "replay.toml"
    rig.write_text(text.replace('url = "sim://load_cell"', f'url = "replay://{rec}"'))
    (tmp_path / "sim.thrust_map.csv").write_text(
        (RIGS / "sim.thrust_map.csv").read_text())
    err = run_bad(capsys, "check", "--rig", str(rig))
    assert "rec.npz: not a NumPy .npz file (expected an .npz recording" in err
    assert "pickle" not in err
    rec.unlink()
    err = run_bad(capsys, "check", "--rig", str(rig))
    assert "rec.npz not found" in err


def test_check_deep_save_is_checked_before_listening(tmp_path: Path, capsys,
                                                     fixtures_dir: Path) -> None:
    """A folder, a path below a file or the rig itself as --save were tracebacks (or
    replaced the rig file) after the listening."""
    rig = tmp_path / "rig.toml"
    rig.write_text((RIGS / "sim.toml").read_text())
    (tmp_path / "sim.thrust_map.csv").write_text(
        (RIGS / "sim.thrust_map.csv").read_text())
    (tmp_path / "folder").mkdir()
    base = ["check", "--rig", str(rig), "--deep", "--seconds", "0.2", "--save"]
    err = run_bad(capsys, *base, str(tmp_path / "folder"))
    assert "--save" in err and "is a folder; expected the name of the file" in err
    err = run_bad(capsys, *base, str(rig / "report.json"))
    assert "rig.toml is a file, not a folder" in err
    text = rig.read_text()
    err = run_bad(capsys, *base, str(rig))
    assert "is also an input" in err and rig.read_text() == text
    err = run_bad(capsys, "check", "--rig", str(rig), "--save", str(tmp_path / "r.json"))
    assert "--save: only applies with --deep" in err
