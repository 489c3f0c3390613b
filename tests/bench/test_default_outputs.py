"""The commands' default outputs stay out of the repository's status."""

from __future__ import annotations

from pathlib import Path

import pytest


def test_default_outputs_are_git_ignored(tmp_path: Path) -> None:
    """Run from a checkout, the commands' default outputs (./runs, ./demo-out of `make demo`,
    ./report-<run id>) must not show up as untracked files."""
    import shutil
    import subprocess

    repo = Path(__file__).resolve().parents[2]
    if shutil.which("git") is None or not (repo / ".git").exists():
        pytest.skip("not a git checkout")
    paths = ["runs/x/run.json", "demo-out/tables/x.csv", "report-20260101T000000Z-step1/x.png"]
    proc = subprocess.run(["git", "-C", str(repo), "check-ignore", "--no-index", *paths],
                          capture_output=True, text=True, check=False)
    assert sorted(proc.stdout.split()) == sorted(paths), proc.stderr
