"""What the user gave on the command line, and the value types the commands share.

``bench.cli.main`` keeps every option's argparse default (:func:`option_defaults`), so a
command can tell an option given from one left alone (:func:`given_options`) and refuse
one that would be silently ignored (:func:`refuse_unused`).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from typing import Any

from optimizer.errors import RequestError

__all__ = ["given_options", "option_defaults", "refuse_unused", "seed_arg"]


def option_defaults(parser: argparse.ArgumentParser, args: argparse.Namespace) -> dict:
    """The argparse defaults of every option of the command (and sub-command) that
    ``args`` ran, by ``dest``: what an option holds when the user did not give it.
    ``bench.cli.main`` keeps them in ``args._defaults`` for :func:`given_options`."""
    defaults: dict = {}
    while True:
        defaults.update({a.dest: a.default for a in parser._actions
                         if a.dest != argparse.SUPPRESS})
        sub = next((a for a in parser._actions if isinstance(a, argparse._SubParsersAction)),
                   None)
        name = getattr(args, sub.dest, None) if sub is not None else None
        if sub is None or name not in sub.choices:
            return defaults
        parser = sub.choices[name]


def given_options(args: argparse.Namespace, *flags: str) -> list[str]:
    """Which of ``flags`` (``--tip-speed-max``) the user gave: the option's value differs
    from its argparse default. Without ``args._defaults`` (:func:`option_defaults`; a
    handler called as a library) nothing is known to be given."""
    defaults = getattr(args, "_defaults", None) or {}
    out = []
    for flag in flags:
        dest = flag.lstrip("-").replace("-", "_")
        if dest not in defaults:
            continue
        value, default = getattr(args, dest, None), defaults[dest]
        if not (value is default or (value == default and not _is_nan(value))):
            out.append(flag)
    return out


def refuse_unused(args: argparse.Namespace, flags: Sequence[str], context: str) -> None:
    """Refuse (exit 2) options that would be silently ignored: ``context`` says when they
    have no effect, e.g. ``"without --flyable"`` or ``"for export px4"``. One place for
    every command's "option X only with Y" rule, so none of them just drops an option."""
    unused = given_options(args, *flags)
    if unused:
        verb = "has" if len(unused) == 1 else "have"
        raise RequestError(f"{', '.join(unused)} {verb} no effect {context}")


def _is_nan(value: Any) -> bool:
    return isinstance(value, float) and math.isnan(value)


def seed_arg(text: str) -> int:
    """argparse ``type`` of every ``--seed``: a whole number >= 0 (numpy's generators refuse
    a negative seed with a traceback long after the options were read)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {text!r}")
    return value
