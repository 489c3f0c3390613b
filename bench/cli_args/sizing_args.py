"""The option groups the sizing commands (``optimize``, ``evaluate``, ``pareto``, ``fly``)
share: the catalog (:func:`add_catalog_args`), the hover margin (:func:`add_hover_args`,
:func:`hover_margin_from_args`), the measured constants (:func:`add_measured_args`,
:func:`measured_from_args`), the flyable-design rules (:func:`add_rule_args`,
:func:`rules_from_args`) and battery packs, plus their JSON encoder (:func:`json_default`)
and the exit status when nothing is feasible. The work behind them lives in library
modules (``bench.store.catalogs``, ``bench.store.measured_constants``,
``optimizer.model.flyable``); here is only argparse.
"""

from __future__ import annotations

import argparse
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.cli_args.option_values import refuse_unused
from bench.cli_args.store_args import DEFAULT_RUNS_ROOT
from optimizer.errors import RequestError

__all__ = [
    "EXIT_NO_FEASIBLE",
    "RULE_FLAGS",
    "HoverMargin",
    "add_catalog_args",
    "add_hover_args",
    "add_measured_args",
    "add_pack_args",
    "add_rule_args",
    "hover_margin_from_args",
    "json_default",
    "measured_from_args",
    "packs_from_args",
    "rules_from_args",
]

#: Exit status of a sizing command when no requested actuator count has a feasible design.
EXIT_NO_FEASIBLE = 3


def add_catalog_args(p: argparse.ArgumentParser) -> None:
    """``--catalog``, ``--payload-kg`` and ``--json`` of the sizing commands."""
    p.add_argument(
        "--catalog",
        type=Path,
        default=None,
        help="catalog folder, or the name of a shipped one (thesis-e, thesis-d; "
             "default: the shipped thesis-e)",
    )
    p.add_argument("--payload-kg", type=float, default=0.0, help="payload mass (default 0)")
    p.add_argument(
        "--current-model",
        choices=("thesis", "drive"),
        default=None,
        help="what the battery delivers, for every current, power and flight time of the "
             "run: 'thesis' = the propellers' shaft power (E.67, Papers D and E), 'drive' = "
             "the motors' electric power with winding loss (eCalc-like); default: the "
             "catalog's current_model (thesis unless catalog.toml says otherwise)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")


def add_hover_args(p: argparse.ArgumentParser) -> None:
    """``--min-thrust-to-weight`` and ``--thesis-rules``: which designs a command may offer."""
    from optimizer.catalogs.model_constants import DEFAULT_MIN_THRUST_TO_WEIGHT

    g = p.add_argument_group("hover margin (docs/optimizer.md)")
    g.add_argument("--min-thrust-to-weight", type=float, default=None, metavar="R",
                   help="every design offered must reach a full-throttle thrust of all "
                   f"actuators >= R x its weight (default {DEFAULT_MIN_THRUST_TO_WEIGHT:g}: "
                   "hover with control margin; a catalog's own higher min_thrust_to_weight "
                   "stays)")
    g.add_argument("--thesis-rules", action="store_true",
                   help="the thesis' model as printed: no hover check (Tables E.8-E.10 are "
                   "reproduced under it; designs that cannot hover are named in warnings)")


@dataclass(frozen=True)
class HoverMargin:
    """The hover margin of one run: the thrust-to-weight every offered design reaches, or
    None under the thesis' rules, and what decided it (for the output)."""

    ratio: float | None
    source: str

    def apply(self, catalog: Any) -> Any:
        """``catalog`` with the margin as its ``min_thrust_to_weight`` check."""
        from bench.store.catalogs import with_min_thrust_to_weight

        return with_min_thrust_to_weight(catalog, self.ratio)

    def to_dict(self, catalog: Any) -> dict[str, Any]:
        """JSON: ``min_thrust_to_weight`` in force (the catalog's own included), rules."""
        return {"min_thrust_to_weight": catalog.constants.min_thrust_to_weight,
                "thesis_rules": self.ratio is None, "source": self.source}

    def describe(self, catalog: Any) -> str:
        """One line for the text output."""
        own = catalog.constants.min_thrust_to_weight
        if self.ratio is None:
            line = (f"thesis rules ({self.source}): no hover check, as in Papers D and E; "
                    "warnings name chosen designs that cannot hover")
            if own is not None:
                line += f"; the catalog's own min_thrust_to_weight {own:g} applies"
            return line
        return (f"hover margin: every design reaches full-throttle thrust-to-weight >= "
                f"{own:g} ({self.source}; --thesis-rules for the thesis' model)")


def hover_margin_from_args(args: argparse.Namespace,
                           implied_by: str | None = None) -> HoverMargin:
    """The run's :class:`HoverMargin`. ``implied_by`` names an option that means the thesis'
    rules unless ``--min-thrust-to-weight`` is given (``--paper-e-cases``)."""
    from optimizer.catalogs.model_constants import DEFAULT_MIN_THRUST_TO_WEIGHT

    given = getattr(args, "min_thrust_to_weight", None)
    if given is not None and not (math.isfinite(given) and given >= 1.0):
        raise RequestError(f"--min-thrust-to-weight: expected a number >= 1 (below 1 a design "
                           f"cannot hover; --thesis-rules drops the check), got {given:g}")
    if getattr(args, "thesis_rules", False):
        if given is not None:
            raise RequestError("--min-thrust-to-weight does not combine with --thesis-rules "
                               "(the thesis' model has no hover check)")
        return HoverMargin(None, "--thesis-rules")
    if given is not None:
        return HoverMargin(given, "--min-thrust-to-weight")
    if implied_by is not None:
        return HoverMargin(None, f"implied by {implied_by}")
    return HoverMargin(DEFAULT_MIN_THRUST_TO_WEIGHT, "default")


def add_measured_args(p: argparse.ArgumentParser) -> None:
    """``--measured [DIR]`` and ``--esc-mode``: the constants store as the optimizer's
    measured overrides (``bench.store.measured_constants``)."""
    p.add_argument(
        "--measured",
        type=str,
        nargs="?",
        const="",
        default=None,
        metavar="DIR|URL",
        help="use measured time constants and hover currents from DIR/constants.sqlite "
        "where a combination has them (default DIR: $ROTORBENCH_STORE, else ./runs; a demo "
        "output folder works), or from the lab catalog postgresql://...",
    )
    p.add_argument(
        "--esc-mode",
        default=None,
        help="with --measured: which ESC mode's constants (default: the mode stored for "
        "the most combinations)",
    )


def measured_from_args(args: argparse.Namespace, catalog: Any) -> Any:
    """The ``MeasuredSet`` of ``--measured``/``--esc-mode`` for ``catalog`` (None without
    ``--measured``; ``--esc-mode`` alone is refused)."""
    if getattr(args, "measured", None) is None:
        if getattr(args, "esc_mode", None) is not None:
            raise RequestError("--esc-mode only applies with --measured")
        return None
    from bench.store.constants_store import ActuatorKey, ConstantsRow
    from bench.store.measured_constants import load_measured_set
    from bench.store.store_url import STORE_ENV, parse_store

    url = parse_store(args.measured or os.environ.get(STORE_ENV) or str(DEFAULT_RUNS_ROOT))
    if url.folder is not None:
        from bench.paths.inputs import check_input

        return load_measured_set(check_input(url.folder, "--measured"), catalog, args.esc_mode)
    from bench.store.lab_catalog import LabCatalog

    assert url.dsn is not None
    rows = [ConstantsRow(ActuatorKey(c.motor, c.propeller, c.esc, c.esc_mode, c.battery,
                                     c.catalog), c.kind, c.run_id, c.run_path, c.fitted_utc,
                         c.data) for c in LabCatalog(url.dsn).constants()]
    return load_measured_set(url.shown(), catalog, args.esc_mode, rows=rows)


#: the rule switches that only act with --flyable
RULE_FLAGS = ("--no-rule", "--tip-speed-max", "--max-wheelbase-m", "--hover-throttle",
              "--rule-max-time-constant-ms")


def add_rule_args(p: argparse.ArgumentParser) -> None:
    """``--flyable`` and its rule switches (optimizer.model.flyable)."""
    from optimizer.model.flyable import RULE_NAMES, Rules

    d = Rules()
    g = p.add_argument_group("flyable-design rules (docs/sizing.md)")
    g.add_argument("--flyable", action="store_true",
                   help=f"apply the rules {', '.join(RULE_NAMES)} and report what each removes")
    g.add_argument("--no-rule", action="append", default=[], choices=RULE_NAMES,
                   metavar="NAME", help="switch one rule off (repeatable)")
    g.add_argument("--tip-speed-max", type=float, default=d.tip_speed_m_s, metavar="M_S",
                   help=f"rule tip-speed: full-throttle tip speed limit (default "
                   f"{d.tip_speed_m_s:g} m/s)")
    g.add_argument("--max-wheelbase-m", type=float, default=d.max_wheelbase_m, metavar="M",
                   help=f"rule frame: motor-to-motor diagonal limit (default "
                   f"{d.max_wheelbase_m:g} m)")
    g.add_argument("--hover-throttle", type=float, nargs=2, default=d.hover_throttle_pct,
                   metavar=("LO", "HI"), help="rule hover-throttle: band in percent "
                   "(default 30 70)")
    g.add_argument("--rule-max-time-constant-ms", type=float, default=d.max_time_constant_ms,
                   metavar="MS", help=f"rule response: time-constant limit (default "
                   f"{d.max_time_constant_ms:g} ms)")


def rules_from_args(args: argparse.Namespace) -> Any:
    """The ``Rules`` of ``--flyable`` (None without it)."""
    from optimizer.model.flyable import RULE_NAMES, Rules

    if not getattr(args, "flyable", False):
        refuse_unused(args, RULE_FLAGS, "without --flyable")
        return None
    return Rules(
        enabled=tuple(r for r in RULE_NAMES if r not in args.no_rule),
        tip_speed_m_s=args.tip_speed_max,
        max_wheelbase_m=args.max_wheelbase_m,
        hover_throttle_pct=tuple(args.hover_throttle),
        max_time_constant_ms=args.rule_max_time_constant_ms,
    ).validate()


def add_pack_args(p: argparse._ActionsContainer) -> None:
    """``--series`` and ``--parallel``: cells in series and parallel (optimizer.solve.packs)."""
    p.add_argument("--series", default=None, metavar="S",
                   help="choose cells in series too, e.g. 2-6 (the catalog's batteries read "
                   "as cells, docs/sizing.md)")
    p.add_argument("--parallel", default=None, metavar="P",
                   help="with --series: parallel strings, e.g. 1-4 (default 1)")


def packs_from_args(args: argparse.Namespace) -> tuple[tuple[int, ...], tuple[int, ...]] | None:
    """(series counts, parallel counts) of ``--series``/``--parallel``; None without them."""
    if args.series is None and args.parallel is None:
        return None
    if args.series is None:
        raise RequestError("--parallel needs --series (e.g. --series 2-6 --parallel 1-4)")
    from optimizer.solve.packs import parse_counts

    return (parse_counts(args.series, "--series"),
            parse_counts(args.parallel or "1", "--parallel"))


def json_default(obj: Any) -> Any:
    """``json.dumps(default=...)`` of the sizing commands: numpy scalars, tuples, sets."""
    if hasattr(obj, "item"):
        return obj.item()
    if isinstance(obj, tuple | set):
        return list(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")
