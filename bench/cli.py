"""The ``rotorbench`` command: discovers subcommands in ``bench.commands``.

Errors caused by the user's input (bad file, rig, catalog, device bytes) are
exceptions with an ``exit_code`` attribute; they are printed as one line and
the process exits with that code, without a traceback. Anything else is a bug
and keeps its traceback.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from collections.abc import Sequence

from bench import commands

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
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
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("rotorbench: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        code = getattr(exc, "exit_code", None)
        if code is None:
            raise
        print(f"rotorbench: error: {exc}", file=sys.stderr)
        return int(code)


if __name__ == "__main__":
    sys.exit(main())
