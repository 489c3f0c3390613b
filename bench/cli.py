"""The ``rotorbench`` command: discovers subcommands in ``bench.commands``.

Start-up matters (a 20-repeat simulated step takes about as long as importing every
command with its numpy/scipy/pandas/matplotlib dependencies), so ``main`` imports only the
module of the command it was given (the module named like the command, or the one
``_MODULE_OF`` names); ``--help`` or an unknown command builds the full parser.

Errors caused by the user's input (bad file, rig, catalog, device bytes) are
exceptions with an ``exit_code`` attribute; they are printed as one line and
the process exits with that code, without a traceback. Anything else is a bug
and keeps its traceback.

The modules log to ``logging`` (``bench.engine.run_log``: every run keeps its lines in
``run.log``); on the terminal, stderr shows warnings, ``-v`` adds what the bench does
and ``-vv`` the details; ``--log-level`` names the level. stdout keeps only the
command's own output (tables, JSON).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import logging
import os
import pkgutil
import sys
from collections.abc import Sequence
from pathlib import Path

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
    _add_log_options(parser, top=True)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in [only] if only is not None else _command_modules():
        module = importlib.import_module(f"{commands.__name__}.{name}")
        module.register(sub)
    for command in sub.choices.values():
        _add_log_options(command)
    return parser


LOG_LEVELS = ("debug", "info", "warning", "error")


def _add_log_options(parser: argparse.ArgumentParser, top: bool = False) -> None:
    """``-v``/``--log-level`` before or after the command (and its own subcommands)."""
    default = None if top else argparse.SUPPRESS  # a command's own never hides the top's
    group = parser.add_argument_group("diagnostics")
    group.add_argument("-v", "--verbose", action="count", default=0 if top else default,
                       help="log what the bench does to stderr (-vv: the details too)")
    group.add_argument("--log-level", choices=LOG_LEVELS, type=str.lower, default=default,
                       help="the least level logged to stderr (default: warning; every "
                            "run keeps its whole log in run.log)")
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in action.choices.values():
                _add_log_options(child)


class _StderrHandler(logging.StreamHandler):
    """Writes to whatever ``sys.stderr`` is when a line is logged, not to the stream it
    was at set-up: a caller that swaps stderr (a test's capture, a console redirect) and
    closes the old one must not turn every later warning into a logging error."""

    def __init__(self) -> None:
        super().__init__(sys.stderr)

    def emit(self, record: logging.LogRecord) -> None:
        self.stream = sys.stderr  # (setStream would flush the old one, which may be closed)
        super().emit(record)


def configure_logging(verbose: int = 0, level: str | None = None) -> logging.Handler:
    """stderr's share of the log: ``level``, else warnings and up, ``-v`` info, ``-vv``
    debug, of the project's loggers (other libraries': warnings, whatever the level).
    Returns the handler (a second call replaces the first's)."""
    from bench.engine.run_log import PACKAGES

    if level is None:
        level = ("warning", "info", "debug")[min(max(verbose, 0), 2)]
    root = logging.getLogger()
    for old in [h for h in root.handlers if getattr(h, "_rotorbench", False)]:
        root.removeHandler(old)
    handler = _StderrHandler()
    handler.setLevel(getattr(logging, level.upper()))
    handler.setFormatter(logging.Formatter("rotorbench: %(levelname)s: %(name)s: %(message)s"))
    handler._rotorbench = True  # type: ignore[attr-defined]
    root.addHandler(handler)
    for name in PACKAGES:
        logging.getLogger(name).setLevel(handler.level)
    return handler


#: the commands whose module cannot be named like them (``import`` is a Python keyword)
_MODULE_OF = {"import": "import_log"}


def _parser_for(argv: Sequence[str]) -> argparse.ArgumentParser:
    """A parser holding only the given command when its module is named like it (the
    command's own ``--help`` and errors are the same either way), else the full one."""
    if argv and not argv[0].startswith("-"):
        first = argv[0]
        name = _MODULE_OF.get(first, first.replace("-", "_"))
        if name in _command_modules():
            parser = build_parser(only=name)
            sub = next(a for a in parser._actions
                       if isinstance(a, argparse._SubParsersAction))
            if first in sub.choices:
                return parser
    return build_parser()


#: Path options that name outputs (checked by each command's ``check_writable``); every
#: other Path argument is an input, checked by :func:`_check_inputs` before the command runs.
_OUTPUTS = frozenset({"out", "apply_out", "figures", "plot", "png", "save", "screenshot",
                      "simulate_log"})


def _flags(parser: argparse.ArgumentParser, argv: Sequence[str]) -> dict[str, str]:
    """The option string of each destination of the command given (positionals: '')."""
    flags: dict[str, str] = {}
    stack = [parser]
    while stack:
        p = stack.pop()
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                stack.extend(sub for name, sub in action.choices.items() if name in argv)
            else:
                flags.setdefault(action.dest, max(action.option_strings, key=len, default=""))
    return flags


def _check_inputs(parser: argparse.ArgumentParser, argv: Sequence[str],
                  args: argparse.Namespace) -> None:
    """Refuse an input path that is a symlink loop, a device or a FIFO before any command
    reads it (``decode /dev/zero`` filled 18 GB; a looping --rig link was a traceback)."""
    from bench.paths.inputs import check_input

    flags = _flags(parser, argv)
    for dest, value in vars(args).items():
        if dest in _OUTPUTS:
            continue
        for v in value if isinstance(value, list) else [value]:
            if isinstance(v, os.PathLike):
                check_input(Path(v), flags.get(dest, ""))


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
    configure_logging(getattr(args, "verbose", 0) or 0, getattr(args, "log_level", None))
    from bench.cli_args.option_values import option_defaults

    args._defaults = option_defaults(parser, args)  # for refuse_unused
    try:
        _check_inputs(parser, argv, args)
        from bench.engine.sigterm import sigterm_as_interrupt

        # `kill PID` ends every command like Ctrl-C (safe stop, clean-up), exit 143
        with _plain_numbers(), sigterm_as_interrupt():
            return int(args.func(args) or 0)
    except KeyboardInterrupt as exc:
        if "SIGTERM" in exc.args:  # bench.engine.sigterm.sigterm_as_interrupt
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
        print(f"rotorbench: error: {short_message(str(exc))}", file=sys.stderr)
        return int(code)


#: longest error line printed; a message quoting the user's input (a cell, a TOML value,
#: a file's line) is cut in its middle beyond this, keeping where (the start) and why (the
#: end). The readers quote short excerpts themselves; this is the net under all of them.
MESSAGE_MAX_CHARS = 1000


def short_message(text: str, limit: int = MESSAGE_MAX_CHARS) -> str:
    """``text`` if short, else its start and end around a note of what was left out."""
    if len(text) <= limit:
        return text
    head, tail = text[: limit * 3 // 4], text[-(limit // 5):]
    return f"{head} ... ({len(text) - len(head) - len(tail)} characters left out) ... {tail}"


if __name__ == "__main__":
    sys.exit(main())
