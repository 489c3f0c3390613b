"""The windows' options (the console, --live) are checked before any window opens."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import run_bad


def test_live_without_a_display(tmp_path: Path, capsys, monkeypatch) -> None:
    """Qt aborted the process (exit 134, Qt's text) when no display was there."""
    import sys

    if not sys.platform.startswith("linux"):
        pytest.skip("the display check is for Linux")
    for var in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM"):
        monkeypatch.delenv(var, raising=False)
    out = tmp_path / "runs"
    err = run_bad(capsys, "step", "--live", "--repeats", "1", "--out", str(out))
    assert "--live needs a display" in err
    assert not out.exists()


@pytest.mark.parametrize(("extra", "expected"), [
    (["--window", "nan"], "--window nan: expected 0 < seconds <= 60"),  # NaN to integer
    (["--selftest", "--min-fps", "inf"], "--min-fps inf: expected a refresh rate"),
    (["--selftest", "--min-fps", "-1"], "--min-fps -1: expected a refresh rate"),
    (["--selftest", "--screenshot", "shot.txt"], "expected a file name ending in .png"),
    (["--selftest", "--screenshot", "afile/shot.png"], "afile is a file, not a folder"),
    (["--selftest", "--out", "afile"], "--out afile: is a file; expected a folder"),
    (["--min-fps", "3"], "--min-fps: only applies with --selftest"),  # opened the window
    (["--screenshot", "shot.png"], "--screenshot: only applies with --selftest"),
])
def test_console_options_are_checked_before_the_window(tmp_path: Path, capsys, monkeypatch,
                                                       extra: list[str],
                                                       expected: str) -> None:
    """The self-test reported bad paths as FAIL (exit 1) after running the rig."""
    monkeypatch.chdir(tmp_path)
    Path("afile").write_text("x")
    err = run_bad(capsys, "console", *extra)
    assert expected in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


@pytest.mark.parametrize("min_fps, code", [(30.0, 1), (0.0, 0)])
def test_the_selftest_holds_the_window_to_its_frame_rate_floor(tmp_path: Path, capsys,
                                                               min_fps, code) -> None:
    """A window that refreshed 28.8 times a second fails the default floor (30), and passes
    with ``--min-fps 0``: the floor is the user's check of their machine."""
    from types import SimpleNamespace

    import pandas as pd

    from bench.commands.console import _selftest_verdict

    pd.DataFrame({"throttle_us": [1000.0, 1300.0, 1000.0]}).to_parquet(
        tmp_path / "samples.parquet")
    bench = SimpleNamespace(selftest={
        "ok": True, "frames_per_s": 28.8, "size": (1100, 680), "screenshot": "shot.png",
        "finished": {"status": "success", "reason": "", "run_dir": str(tmp_path)}})
    rig = SimpleNamespace(esc=SimpleNamespace(idle_us=1000.0))
    assert (_selftest_verdict(bench, rig, min_fps) != 0) == bool(code)
    err = capsys.readouterr().err
    assert ("plot refresh 28.8 frames/s < 30" in err) == bool(code)
