"""Helpers every CLI command shares (the one home: commands never import each other).

The bench commands' common arguments (``--rig``, ``--out``, ``--limit``, ...), reading
them (the rig, the limits, the loop options) and the dry-run listing; and the output
check every writing command makes on its output path before any work.

And the option groups the sizing commands (``optimize``, ``evaluate``, ``pareto``, ``fly``)
share: the catalog (:func:`add_catalog_args`), the hover margin (:func:`add_hover_args`,
:func:`hover_margin_from_args`), the measured constants
(:func:`add_measured_args`, :func:`measured_from_args`) and the flyable-design rules
(:func:`add_rule_args`, :func:`rules_from_args`), plus their JSON encoder
(:func:`json_default`) and the exit status when nothing is feasible. The work behind
them lives in library modules (``bench.store.catalogs``, ``bench.store.measured_constants``,
``optimizer.model.flyable``); here is only argparse and output.

A command that would run for minutes (a demo, a calibration on the rig) and then fail to
write its result wastes the run; a traceback at the end says nothing useful. So each
command names its outputs up front and :func:`check_writable` refuses, in one line with
exit code 2, a path that cannot be written: a regular file where a folder must be (or
the reverse), a missing folder the command does not create, a folder the user may not
write in (read-only, immutable, read-only file system). Writability is probed by creating
and removing a hidden temporary file, the only test that is right for every user
(``os.access`` says yes to root on a read-only folder, no on some network mounts).
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.errors import RigError
from optimizer.errors import RequestError

__all__ = [
    "DEFAULT_OUT",
    "DEFAULT_RUNS_ROOT",
    "EXIT_NO_FEASIBLE",
    "RULE_FLAGS",
    "add_catalog_args",
    "add_common_arguments",
    "add_hover_args",
    "add_measured_args",
    "add_pack_args",
    "add_rule_args",
    "check_writable",
    "given_options",
    "hover_margin_from_args",
    "json_default",
    "load_rig_from_args",
    "measured_from_args",
    "option_defaults",
    "packs_from_args",
    "parse_limits",
    "print_dry_run",
    "refuse_unused",
    "rules_from_args",
    "run_options_from_args",
    "seed_arg",
]

#: The output root of every command's runs and runs.sqlite (``--out``).
DEFAULT_OUT = Path("runs")
#: The same root, named for the sizing commands that read the constants store in it.
DEFAULT_RUNS_ROOT = DEFAULT_OUT

#: Exit status of a sizing command when no requested actuator count has a feasible design.
EXIT_NO_FEASIBLE = 3


def check_folder_to_read(path: Path, flag: str = "--out") -> Path:
    """A folder a command lists (runs, constants): a file there is a mistake said now,
    a folder not made yet simply holds nothing."""
    from bench.rig.input_paths import refuse_loop

    path = Path(path)
    # exists() is False for a loop: it read as an empty folder
    refuse_loop(path, f"{flag} {path}", "a folder of runs")
    if path.exists() and not path.is_dir():
        raise RigError(f"{flag} {path}: is a file; expected a folder of runs")
    return path


#: figure formats a ``--plot FILE`` may name (matplotlib's Agg backend writes them)
FIGURE_SUFFIXES = (".png", ".pdf", ".svg")


def check_figure_path(path: Path, flag: str = "--plot",
                      suffixes: tuple[str, ...] = FIGURE_SUFFIXES,
                      inputs: Sequence[Path | None] = ()) -> Path:
    """Refuse, before any work, a figure file that could not be written or whose suffix is
    no figure format (matplotlib would append ``.png`` to a bare name, or fail late);
    ``suffixes``: the formats the writer knows (default: matplotlib's); ``inputs``: the
    files the command reads (never overwritten)."""
    path = Path(path)
    if path.suffix.lower() not in suffixes:
        raise RequestError(f"{flag} {path}: expected a file name ending in "
                           f"{', '.join(suffixes)}")
    return check_writable(path, flag, folder=False, inputs=inputs)


def check_writable(path: Path, flag: str, *, folder: bool, beside: bool = False,
                   make_parents: bool = True, inputs: Sequence[Path | None] = ()) -> Path:
    """Refuse (``RigError``) an output ``path`` that cannot be written; return it.

    ``folder``: the output is a folder (a run root, a report) rather than a file.
    ``beside``: the folder is built beside its final name and renamed into place, so
    its parent must be writable even when the folder exists.
    ``make_parents``: the command creates missing parent folders; if not, the parent
    must exist.
    ``inputs``: the files the command reads; an output that is one of them is refused
    (writing it would replace the data it is computed from).
    """
    path = Path(path)
    where = f"{flag} {path}" if flag else str(path)
    for source in inputs:
        if source is not None and _same_file(path, Path(source)):
            raise RigError(f"{where}: is also an input ({source}); choose another name "
                           "for the output")
    if path.exists() or path.is_symlink():
        if folder and not path.is_dir():
            raise RigError(f"{where}: is a file; expected a folder")
        if not folder and path.is_dir():
            raise RigError(f"{where}: is a folder; expected the name of the file to write")
    # where the new entries go: into an existing folder, else beside the path
    target = path if folder and path.is_dir() and not beside else path.parent
    anchor = target
    while not anchor.exists() and anchor != anchor.parent:
        anchor = anchor.parent  # the nearest folder that exists: the command creates the rest
    if not anchor.is_dir():
        raise RigError(f"{where}: {anchor} is a file, not a folder")
    if not make_parents and anchor != target:
        raise RigError(f"{where}: folder {target} does not exist")
    problem = _probe(anchor)
    if problem is not None:
        raise RigError(f"{where}: cannot write in {anchor} ({problem})")
    return path


def _same_file(a: Path, b: Path) -> bool:
    """Whether ``a`` and ``b`` name the same file (through links, ``..`` and case)."""
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def _probe(folder: Path) -> str | None:
    """Why a new file cannot be created in ``folder`` (None if it can)."""
    try:
        fd, name = tempfile.mkstemp(prefix=".rotorbench-probe-", dir=folder)
    except OSError as exc:
        return exc.strerror or str(exc)
    os.close(fd)
    os.unlink(name)
    return None


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


# --- the bench commands' arguments (step, sweep, console) -----------------------------------
def add_common_arguments(p: argparse.ArgumentParser) -> None:
    from bench.run.safety import LIMIT_FIELDS

    p.add_argument("--rig", type=Path, default=None,
                   help="rig file (TOML); default: the simulated rig bench/data/rigs/sim.toml")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT,
                   help="output root for run folders and runs.sqlite (default: ./runs); with "
                        "a lab --store, the data location (s3://bucket/prefix or a shared "
                        "folder)")
    p.add_argument("--esc-mode", choices=("complementary", "diode", "stock"), default=None,
                   help="ESC switching scheme / firmware (overrides the rig file)")
    p.add_argument("--seed", type=seed_arg, default=None, help="seed of the simulated rig")
    p.add_argument("--limit", action="append", default=[], metavar="NAME=VALUE",
                   help=f"tighten a limit for this run ({', '.join(LIMIT_FIELDS)}); "
                        "loosening is refused")
    p.add_argument("--dry-run", action="store_true",
                   help="print every step with times and commands; touch no device")
    p.add_argument("--live", action="store_true",
                   help="show rolling plots in a window (pyqtgraph); implies --realtime")
    p.add_argument("--realtime", action="store_true",
                   help="pace a simulated rig to the wall clock")
    p.add_argument("--yes", action="store_true",
                   help="run a plan longer than 1 h or projected above 2 GB of samples "
                        "(refused without it; a plan longer than 24 h is always refused)")
    p.add_argument("--tick", type=float, default=0.02,
                   help="command/read period in seconds; limits are checked on every "
                        "sample, the reaction comes within one tick (default 0.02)")
    add_store_args(p, records=True)


def load_rig_from_args(args: argparse.Namespace, prefer_out_copy: bool = False) -> Any:
    """The rig of ``--rig`` (default: the sim rig), with ``--esc-mode`` applied.

    ``prefer_out_copy``: for a read-only rig (shipped, or not writable) use the copy an
    earlier sweep stored under ``<out>/rigs/`` with its measured map, if there is one.
    """
    from bench.rig.rig import default_rig_path, load_rig, map_goes_to_copy, rig_copy_path

    rig = load_rig(args.rig or default_rig_path())
    if prefer_out_copy and map_goes_to_copy(rig):
        copy = rig_copy_path(rig.path, args.out)
        if copy.is_file():
            print(f"rig file: {copy} (the copy of read-only {rig.path} that holds the "
                  "map a sweep measured)")
            rig = load_rig(copy)
    if args.esc_mode:
        rig = rig.with_esc_mode(args.esc_mode)
    return rig


def parse_limits(items: list[str]) -> dict[str, float]:
    """``--limit NAME=VALUE`` items as a dict (names of ``bench.run.safety.LIMIT_FIELDS``)."""
    from bench.run.safety import LIMIT_FIELDS

    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or name not in LIMIT_FIELDS:
            raise RigError(f"--limit {item!r}: expected NAME=VALUE with NAME one of "
                           f"{', '.join(LIMIT_FIELDS)}")
        try:
            out[name] = float(value)
        except ValueError:
            raise RigError(f"--limit {item!r}: {value!r} is not a number") from None
        if not math.isfinite(out[name]):
            raise RigError(f"--limit {item!r}: expected a finite number")
    return out


def run_options_from_args(args: argparse.Namespace) -> Any:
    """The loop settings of ``--tick``, ``--realtime`` and ``--live`` (which implies it)."""
    from bench.runners.runner import RunOptions

    return RunOptions(tick_s=args.tick, realtime=bool(args.realtime or args.live))


def print_dry_run(rig: Any, seq: Any, note: str | None = None) -> None:
    """The dry run: ``note``, the rig's ESC, every step with times and commands, the
    projection."""
    from bench.plans.run_budget import check_budget, project, row_rate_hz
    from bench.plans.sequences import format_plan
    from bench.run.safety import effective_limits
    from bench.runners.session import plan_for

    effective_limits(rig.limits, seq.limits, source=f"sequence {seq.name!r}",
                     thrust_setpoints_n=seq.thrust_setpoints_n)
    plan = plan_for(rig, seq, dry_run=True)
    budget = project(plan.duration_s, row_rate_hz(rig))
    # a plan no run may carry out is refused before its (millions of) lines are printed;
    # one that needs --yes is shown, the projection says what it costs
    check_budget(budget, seq.where, yes=True)
    if note:
        print(note)
    print(f"rig {rig.name} ({rig.path}); ESC {rig.esc.idle_us:g} us idle, "
          f"{rig.esc.min_us:g}-{rig.esc.max_us:g} us at {rig.esc.frame_rate_hz:g} Hz")
    print(format_plan(plan))
    print(budget.describe())


# --- the sizing commands' option groups (optimize, evaluate, pareto, fly) ---------------
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
        from bench.rig.input_paths import check_input

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


# -- where runs and constants live (--store; bench/store, docs/lab.md) -----------------------
def add_store_args(p: argparse.ArgumentParser, *, records: bool = False) -> None:
    """``--store`` (a folder or the lab catalog); recording commands also get ``--spool``
    and ``--bench``."""
    p.add_argument("--store", metavar="DIR|URL", default=None,
                   help="where runs and constants live: a folder (default: --out, or "
                        "$ROTORBENCH_STORE) or the lab catalog postgresql://user@host/db "
                        "(docs/lab.md)")
    if records:
        p.add_argument("--spool", type=Path, default=None,
                       help="lab catalog: where runs are recorded first, on this machine "
                            "(default ~/.local/share/rotorbench/spool)")
        p.add_argument("--bench", default=None,
                       help="this bench's name in the lab catalog (default: the rig file's "
                            "name, else the host name)")


def data_location_text(value: str | os.PathLike[str]) -> str:
    """``--out`` as a data location: ``s3://bucket/prefix`` survives being a ``Path``
    (which folds ``//``) or a folder path."""
    text = os.fspath(value)
    if text.startswith("s3:/") and not text.startswith("s3://"):
        return "s3://" + text[len("s3:/"):]
    return text


def store_from_args(args: argparse.Namespace, *, records: bool = False,
                    out_attr: str = "out") -> Any:
    """The store of a command: ``--store`` or ``$ROTORBENCH_STORE``, else the folder
    ``--out``. With the lab catalog, ``--out`` names the data location (``s3://...`` or a
    shared folder) and a recording command records into the spool: ``args.out`` becomes
    the spool, so everything the command writes beside its runs stays on this machine.
    ``out_attr`` names the run-root option where it is not ``--out`` (calibrate's
    ``--runs``)."""
    from bench.store.store_url import STORE_ENV, parse_store
    from bench.store.stores import FolderStore, open_store

    text = getattr(args, "store", None) or os.environ.get(STORE_ENV)
    flag = "--" + out_attr.replace("_", "-")
    out = getattr(args, out_attr, None)
    if not text:
        if out is not None and data_location_text(out).startswith("s3://"):
            raise RequestError(f"{flag} {data_location_text(out)}: an object store holds the "
                               "lab catalog's runs; give the catalog with --store "
                               "postgresql://... (docs/lab.md)")
        return FolderStore(Path(out if out is not None else DEFAULT_RUNS_ROOT))
    url = parse_store(text)
    if url.folder is not None:
        if out is not None and given_options(args, flag) and \
                Path(out).resolve() != url.folder.resolve():
            raise RequestError(f"{flag} {out} and --store {url.folder} name two folder "
                               "stores; give one")
        if out is not None:
            setattr(args, out_attr, url.folder)
        return FolderStore(url.folder)
    data = data_location_text(out) if out is not None and given_options(args, flag) \
        else None
    store = open_store(text, data=data, spool=getattr(args, "spool", None))
    if records:
        setattr(args, out_attr, store.record_root())
    return store


def recording_store(args: argparse.Namespace, out_attr: str = "out") -> Any:
    """The store a recording command writes to, checked before anything spins (a
    reader-only lab login is refused here); ``--bench`` names the bench in run.json."""
    store = store_from_args(args, records=True, out_attr=out_attr)
    if getattr(args, "bench", None):
        os.environ["ROTORBENCH_BENCH"] = str(args.bench)
    if not getattr(args, "dry_run", False):
        store.check_can_record()
    return store


def publish_runs(store: Any, run_dir: Path | None = None) -> None:
    """After a recording command: the lab store publishes what the spool holds (this run,
    a map sweep before it) and says where each went, or that it waits for ``store sync``."""
    note = store.after_run(run_dir)
    if note:
        print(note)


def run_folder_arg(args: argparse.Namespace, value: str | os.PathLike[str]) -> Path:
    """A RUN argument: a run folder, or a run id of ``--store``/``$ROTORBENCH_STORE``
    (a lab run is fetched into the local cache)."""
    path = Path(value)
    if path.exists() or not (getattr(args, "store", None) or
                             os.environ.get("ROTORBENCH_STORE")):
        return path
    return Path(store_from_args(args).run_folder(str(value)))
