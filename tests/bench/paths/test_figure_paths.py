"""A sizing command's --plot path (bench.paths.outputs.check_figure_path) is checked before
the work, and a new folder for it is made."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.cli import main

SIZING_PLOTS = {
    "evaluate": ["evaluate", "--actuators", "4", "--propeller", "P4", "--motor", "M1",
                 "--battery", "B3"],
    "pareto": ["pareto", "--actuators", "4", "--x", "flight-time", "--y", "time-constant"],
}


@pytest.mark.parametrize("command", sorted(SIZING_PLOTS))
@pytest.mark.parametrize(("name", "expected"), [
    ("in-a-file/x.png", "is a file, not a folder"),  # a file where the folder must be
    ("folder", "expected a file name ending in"),  # would silently become folder.png
    ("bare", "expected a file name ending in"),
    ("table.txt", "expected a file name ending in"),  # matplotlib failed after the work
])
def test_sizing_plot_path_is_checked_before_the_work(tmp_path: Path, capsys, command: str,
                                                     name: str, expected: str) -> None:
    (tmp_path / "in-a-file").write_text("x")
    (tmp_path / "folder").mkdir()
    before = sorted(p.name for p in tmp_path.iterdir())
    code = main([*SIZING_PLOTS[command], "--plot", str(tmp_path / name)])
    err = capsys.readouterr().err
    assert code == 2 and expected in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written


@pytest.mark.parametrize("command", sorted(SIZING_PLOTS))
def test_sizing_plot_writes_a_new_folder_and_file(tmp_path: Path, capsys, command: str) -> None:
    out = tmp_path / "new" / "figure.png"
    assert main([*SIZING_PLOTS[command], "--plot", str(out)]) == 0
    capsys.readouterr()
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
