"""The CLI dispatcher: help lists subcommands, user errors exit 2 without traceback."""

from __future__ import annotations

import subprocess
import sys

from bench.cli import main


def test_help_lists_subcommands(capsys):
    try:
        main(["--help"])
    except SystemExit as exc:
        assert exc.code == 0
    out = capsys.readouterr().out
    assert "COMMAND" in out


def test_no_command_prints_help_and_exits_2(capsys):
    assert main([]) == 2


def test_console_script_runs():
    proc = subprocess.run(
        [sys.executable, "-m", "bench.cli", "--help"], capture_output=True, text=True, check=False
    )
    assert proc.returncode == 0, proc.stderr
    assert "rotorbench" in proc.stdout
