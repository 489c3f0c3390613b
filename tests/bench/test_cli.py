"""The CLI dispatcher: help lists subcommands, user errors exit 2 without traceback."""

from __future__ import annotations

import argparse
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


def _help_of(argv, parser=None, capsys=None) -> str:
    try:
        (parser.parse_args(argv) if parser is not None else main(argv))
    except SystemExit as exc:
        assert exc.code == 0
    return capsys.readouterr().out


def test_a_command_alone_gets_the_same_parser_as_with_all_the_others(capsys):
    """main imports only the given command's module (start-up time); its help, errors and
    arguments are those of the full parser."""
    from bench.cli import _parser_for, build_parser

    full = build_parser()
    for argv in (["step", "--help"], ["calibrate", "apply", "--help"],
                 ["import-sizinglab", "--help"], ["import", "--help"]):
        assert _help_of(argv, capsys=capsys) == _help_of(argv, full, capsys)
    assert vars(_parser_for(["step", "--repeats", "3"]).parse_args(["step", "--repeats", "3"])) \
        .keys() == vars(full.parse_args(["step", "--repeats", "3"])).keys()
    for argv in (["import", "log.csv"], ["import-sizinglab"], ["flight-report", "RUN"]):
        sub = next(a for a in _parser_for(argv)._actions
                   if isinstance(a, argparse._SubParsersAction))
        assert list(sub.choices) == [argv[0]], argv  # not every command's module imported


def test_a_step_run_imports_neither_scipy_nor_pandas(tmp_path):
    """Importing scipy.signal and pandas took longer than a 20-repeat simulated step run."""
    code = ("import sys; from bench.cli import main; "
            f"main(['step', '--repeats', '1', '--out', {str(tmp_path)!r}]); "
            "print(sorted(m for m in ('scipy', 'pandas', 'matplotlib') if m in sys.modules))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=False)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "[]"
