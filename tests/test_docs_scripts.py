"""The scripts that make the docs' figures: they
say what they wrote and what they skipped, and leave nothing behind in the temp folder."""

from __future__ import annotations

import importlib.util
import os
import tempfile
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"


def _script(name: str):
    spec = importlib.util.spec_from_file_location(f"rotorbench_docs_{name}", DOCS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_sizing_figures_report_a_skipped_figure_as_skipped(tmp_path, capsys):
    """Without the SizingLab data it printed sizing_pareto_sizinglab.png as written."""
    figures = _script("make_sizing_figures")
    img = tmp_path / "img"
    written = figures.run(img=img, lab=tmp_path / "no-sizinglab")
    said = capsys.readouterr().out.splitlines()
    target = img / "sizing_pareto_sizinglab.png"
    assert not target.exists() and target not in written
    assert f"skipped {target}: no SizingLab data at {tmp_path / 'no-sizinglab'}" in said
    assert [f"wrote {p}" for p in written] == [s for s in said if s.startswith("wrote ")]
    assert sorted(p.name for p in img.iterdir()) == sorted(p.name for p in written)
    assert all(p.stat().st_size > 10_000 for p in written)


@pytest.mark.parametrize("fails", [False, True])
def test_console_screenshots_remove_their_run_folder(tmp_path, monkeypatch, fails):
    """The runs the screenshots record went to a console-shots-* folder in /tmp that
    stayed there (18 MB per call)."""
    monkeypatch.setenv("QT_QPA_PLATFORM", "offscreen")
    pytest.importorskip("pyqtgraph")
    shots = _script("make_console_screenshots")
    temp = tmp_path / "tmp"
    temp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temp))
    seen: list[Path] = []

    def take(out: Path, img: Path) -> int:  # stands in for driving the console
        seen.append(out)
        (out / "runs").mkdir()
        (out / "runs" / "samples.parquet").write_bytes(os.urandom(1000))
        if fails:
            raise SystemExit("screenshots: timed out waiting")
        return 0

    monkeypatch.setattr(shots, "take_screenshots", take)
    if fails:
        with pytest.raises(SystemExit):
            shots.main(img=tmp_path / "img")
    else:
        assert shots.main(img=tmp_path / "img") == 0
    assert seen and seen[0].parent == temp
    assert list(temp.iterdir()) == []
