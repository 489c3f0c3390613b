"""Only the command layer prints: ``bench/commands/``, ``bench/console/`` and ``bench/cli.py``.

A library module that prints writes into whatever program uses it and cannot be told
apart from the command's own output; user output is the command's to write (a job, a
table or a store takes the ``write``/``show`` callable the command passes), diagnostics
go to ``logging``. Read with ``ast`` so a string or comment saying ``print(`` is no call.
"""

from __future__ import annotations

import ast
from pathlib import Path

BENCH = Path(__file__).resolve().parents[2] / "bench"
#: where printing is the job
ALLOWED = ("commands/", "console/", "cli.py")


def print_calls(source: str) -> list[int]:
    """Line numbers of ``print(...)`` and ``<anything>.print(...)`` calls in ``source``."""
    lines = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call):
            f = node.func
            if (isinstance(f, ast.Name) and f.id == "print") or \
                    (isinstance(f, ast.Attribute) and f.attr == "print"):
                lines.append(node.lineno)
    return lines


def test_the_check_finds_a_print_and_a_console_print_but_no_mention() -> None:
    source = 'x = "print(1)"  # print(2)\nprint(3)\nconsole.print(4)\nlog.info("print")\n'
    assert print_calls(source) == [2, 3]


def test_nothing_outside_the_command_layer_prints() -> None:
    found = []
    for path in sorted(BENCH.rglob("*.py")):
        rel = path.relative_to(BENCH).as_posix()
        if rel.startswith(ALLOWED):
            continue
        found += [f"bench/{rel}:{n}" for n in print_calls(path.read_text(encoding="utf-8"))]
    assert found == [], f"print outside bench/commands, bench/console, bench/cli.py: {found}"
