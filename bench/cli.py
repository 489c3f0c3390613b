"""The ``rotorbench`` command: discovers subcommands in ``bench.commands``.

Start-up matters (a 20-repeat simulated step takes about as long as importing every
command with its numpy/scipy/pandas/matplotlib dependencies), so ``main`` imports only the
module of the command it was given when that module is named like the command; ``--help``,
an unknown command or a command named unlike its module builds the full parser.

Errors caused by the user's input (bad file, rig, catalog, device bytes) are
exceptions with an ``exit_code`` attribute; they are printed as one line and
the process exits with that code, without a traceback. Anything else is a bug
and keeps its traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import pkgutil
import sys
from collections.abc import Sequence

from bench import commands

__all__ = ["build_parser", "main"]


def _command_modules() -> list[str]:
    """The subcommand modules, by name, without importing them."""
    return sorted(m.name for m in pkgutil.iter_modules(commands.__path__)
                  if not m.name.startswith("_"))


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The CLI parser with every subcommand, or with the one of module ``only``."""
    parser = argparse.ArgumentParser(
        prog="rotorbench",
        description="Multirotor propulsion and IMU test bench: run, fit, optimize.",
    )
    from importlib.metadata import PackageNotFoundError, version

    try:
        ver = version("rotorbench")
    except PackageNotFoundError:  # running from a source tree without install
        ver = "unknown"
    parser.add_argument("--version", action="version", version=f"rotorbench {ver}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in [only] if only is not None else _command_modules():
        module = importlib.import_module(f"{commands.__name__}.{name}")
        module.register(sub)
    return parser


def _parser_for(argv: Sequence[str]) -> argparse.ArgumentParser:
    """A parser holding only the given command when its module is named like it (the
    command's own ``--help`` and errors are the same either way), else the full one."""
    if argv and not argv[0].startswith("-"):
        first = argv[0]
        name = first.replace("-", "_")
        if name in _command_modules():
            parser = build_parser(only=name)
            sub = next(a for a in parser._actions
                       if isinstance(a, argparse._SubParsersAction))
            if first in sub.choices:
                return parser
    return build_parser()


def _plain_numbers() -> contextlib.AbstractContextManager[object]:
    """numpy scalars print as numbers (``9.99``, not ``np.float64(9.99)``) in every message
    a command formats, however the value reached the f-string (``!r``, a list, a dict)."""
    import numpy as np

    return np.printoptions(legacy="1.25")


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = _parser_for(argv)
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        with _plain_numbers():
            return int(args.func(args) or 0)
    except KeyboardInterrupt as exc:
        if "SIGTERM" in exc.args:  # bench.run_progress.sigterm_as_interrupt
            print("rotorbench: terminated", file=sys.stderr)
            return 143  # 128 + SIGTERM, as a shell reports a process ended by `kill`
        print("rotorbench: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader went away (`rotorbench export gazebo RUN | head -1`): not a fault of
        # ours; the rest of the output goes nowhere instead of a traceback at exit
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError):  # stdout is not a file (e.g. captured in a test)
            pass
        return 141  # 128 + SIGPIPE, as a shell reports a process killed by a closed pipe
    except Exception as exc:
        code = getattr(exc, "exit_code", None)
        if code is None:
            raise
        print(f"rotorbench: error: {exc}", file=sys.stderr)
        return int(code)


if __name__ == "__main__":
    sys.exit(main())
