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


def test_no_subcommand_help_shows_a_doubled_percent_sign():
    """argparse %-formats help= strings but not descriptions: `step --help` showed '-30 %%'."""
    import argparse

    from bench.cli import build_parser

    parser = build_parser()
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    seen = set()
    todo = list(sub.choices.values())
    while todo:
        p = todo.pop()
        if id(p) in seen:
            continue
        seen.add(id(p))
        text = p.format_help()
        assert "%%" not in text, (p.prog, text)
        todo += [c for a in p._actions if isinstance(a, argparse._SubParsersAction)
                 for c in a.choices.values()]
    assert len(seen) > 15  # every subcommand and `calibrate apply` were looked at
