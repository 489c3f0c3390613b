"""The closed-loop sweep file (``rotorbench fly --sweep --out SWEEP.parquet``), read back.

One Parquet row per design: its keys (``DESIGN_KEYS``), the static model numbers
(``optimizer.model.grid.METRIC_KEYS``, ``thrust_to_weight``), ``can_hover``, per flown maneuver M
``M_rise_time_ms``, ``M_overshoot_pct``, ``M_settling_time_ms``, ``M_saturation_pct`` (null
where undefined: never rose, never settled; robust sweeps add ``_p05``/``_p50``/``_p95``),
and ``error`` (null when the design flew). The key-value metadata ``rotorbench_sweep``
holds the sweep's spec as JSON (``catalog``, ``options``, ``maneuvers``).

Only the columns a question needs are read (pyarrow), so a file of millions of rows answers
in seconds: ``pareto --from`` (:func:`front`) reads two columns and the filters, then the
front's rows; ``optimize --from-sweep`` (``optimizer.sweep.sweep_screen``) reads the roll
rise time, the design keys and the model numbers it checks the file against the catalog with.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from optimizer.errors import RequestError
from optimizer.flight.maneuvers import MANEUVERS
from optimizer.solve.objectives import METRICS, Sense
from optimizer.solve.pareto import enumerate_front
from optimizer.sweep.keys import DESIGN_KEYS as KEYS
from optimizer.sweep.rows import STATIC
from optimizer.sweep.spec import METADATA_KEY

#: The columns that name a design (``series``/``parallel``: the battery pack's cells), as
#: the writer names them (``optimizer.sweep.keys``).
DESIGN_KEYS: tuple[str, ...] = (*KEYS, "design_id")
#: Whether a design flew (``error``: null when it did) and hovers, in every row.
FLAGS: tuple[str, ...] = ("can_hover", "error")
#: The static model numbers of a row, listed with each design of a front.
STATIC_KEYS: tuple[str, ...] = STATIC
#: The Parquet key-value metadata entry that marks a sweep file and holds its spec.
SPEC_KEY = METADATA_KEY.encode()
#: Closed-loop alias suffix -> (column suffix, label, unit, what a null means if not "no").
FIGURES: dict[str, tuple[str, str, str, str | None]] = {
    "rise": ("rise_time_ms", "rise time", "ms", "never rose"),
    "overshoot": ("overshoot_pct", "overshoot", "%", None),
    "settling": ("settling_time_ms", "settling time", "ms", "never settled"),
    "saturation": ("saturation_pct", "saturation", "%", None),
}

def _short(maneuver: str) -> str:
    """``roll_step`` -> ``roll``, ``altitude_step`` -> ``altitude``: the alias stem."""
    return maneuver.removesuffix("_step").replace("_", "-")


_ALIAS = re.compile(rf"(?P<m>[a-z-]+?)-(?P<f>{'|'.join(FIGURES)})(?:-(?P<p>p\d\d))?")
_MANEUVER_OF_SHORT = {_short(m): m for m in MANEUVERS}


@dataclass(frozen=True)
class Axis:
    """One axis of a front: the name given, its column, its sense and its label."""

    name: str
    column: str
    sense: Sense
    label: str

    def cost(self, values: np.ndarray) -> np.ndarray:
        """Lower is better: the values, negated for a maximised column."""
        return values if self.sense == "min" else -values


@dataclass(frozen=True)
class SweepFile:
    """An opened, checked sweep file: its path, spec, row count and column types."""

    path: Path
    spec: dict[str, Any]
    rows: int
    types: dict[str, pa.DataType]

    def numeric(self) -> list[str]:
        """The columns a front can be drawn on: numbers that are not design keys (a column
        with nothing but nulls has the null type: a maneuver in which no design rose)."""
        return [c for c, t in self.types.items() if c not in (*DESIGN_KEYS, *FLAGS)
                and (pa.types.is_integer(t) or pa.types.is_floating(t)
                     or pa.types.is_null(t))]

    def read(self, columns: list[str]) -> pa.Table:
        """Only these columns (a broken file: one line naming it)."""
        try:
            return pq.read_table(self.path, columns=list(dict.fromkeys(columns)))
        except (pa.ArrowException, OSError) as exc:
            raise RequestError(f"{self.path}: cannot read columns {', '.join(columns)} "
                               f"({_first_line(exc)})") from None

    def floats(self, table: pa.Table, column: str) -> np.ndarray:
        """A numeric column as float64, NaN where null (or not a number)."""
        arr = table.column(column).cast(pa.float64())
        return pc.fill_null(arr, math.nan).to_numpy()

    def take(self, positions: np.ndarray, columns: list[str]) -> list[dict[str, Any]]:
        """Rows at ``positions`` (file order) as dicts, reading only the row groups that
        hold them; NaN and null become None."""
        columns = [c for c in dict.fromkeys(columns) if c in self.types]
        if positions.size == 0:
            return []
        try:
            pf = pq.ParquetFile(self.path)
            sizes = np.array([pf.metadata.row_group(g).num_rows
                              for g in range(pf.num_row_groups)])
            starts = np.cumsum(sizes) - sizes
            group_of = np.searchsorted(starts, positions, side="right") - 1
            groups = np.unique(group_of)
            table = pf.read_row_groups(groups.tolist(), columns=columns)
        except (pa.ArrowException, OSError) as exc:
            raise RequestError(f"{self.path}: cannot read rows ({_first_line(exc)})") from None
        # where each wanted row sits in the concatenation of the groups read
        offset = np.cumsum(sizes[groups]) - sizes[groups]
        local = positions - starts[group_of] + offset[np.searchsorted(groups, group_of)]
        picked = table.take(pa.array(local)).to_pylist()
        return [{k: _plain(v) for k, v in row.items()} for row in picked]

    def axis(self, name: str, flag: str) -> Axis:
        """The column and sense of a front axis name (see :func:`resolve_axis`)."""
        return resolve_axis(name, self, flag)


def _first_line(exc: BaseException) -> str:
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]


def _plain(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def open_sweep(path: Path | str, flag: str = "--from") -> SweepFile:
    """Open a sweep file: exists, is Parquet, carries the ``rotorbench_sweep`` spec and the
    columns every sweep has (the design keys, ``can_hover``, ``error``)."""
    path = Path(path)
    where = f"{flag} {path}"
    if not path.exists():
        raise RequestError(f"{where}: no such file")
    if path.is_dir():
        raise RequestError(f"{where}: is a folder; expected a sweep Parquet file "
                           "(rotorbench fly --sweep --out SWEEP.parquet)")
    try:
        meta = pq.read_metadata(path)
        schema = pq.read_schema(path)
    except (pa.ArrowException, OSError) as exc:
        raise RequestError(f"{where}: not a Parquet file ({_first_line(exc)})") from None
    raw = (schema.metadata or {}).get(SPEC_KEY)
    if raw is None:
        raise RequestError(f"{where}: not a rotorbench sweep (no rotorbench_sweep metadata; "
                           "write one with rotorbench fly --sweep --out SWEEP.parquet)")
    try:
        spec = json.loads(raw)
    except (ValueError, UnicodeDecodeError):
        raise RequestError(f"{where}: its rotorbench_sweep metadata is not JSON") from None
    if not isinstance(spec, dict):
        raise RequestError(f"{where}: its rotorbench_sweep metadata is not a JSON object")
    types = {f.name: f.type for f in schema}
    missing = [c for c in (*DESIGN_KEYS[:4], *FLAGS) if c not in types]
    if missing:
        raise RequestError(f"{where}: not a complete sweep, no column "
                           f"{', '.join(missing)}")
    return SweepFile(path, spec, meta.num_rows, types)


def resolve_axis(name: str, sweep: SweepFile, flag: str) -> Axis:
    """The column of a front axis.

    ``name`` is an objective of ``pareto`` (``flight-time``: ``flight_time_min``,
    maximised; ``time-constant``, ``price``, ...), a closed-loop alias
    ``<maneuver>-<rise|overshoot|settling|saturation>[-pNN]`` (``roll-rise`` ->
    ``roll_step_rise_time_ms``, ``roll-rise-p95`` -> its 95th percentile; minimised), or a
    numeric column of the file (minimised). ``max:NAME`` / ``min:NAME`` set the sense.
    """
    sense: Sense | None = None
    base = name
    m = re.fullmatch(r"(min|max):(.+)", name)
    if m:
        sense, base = m.group(1), m.group(2)  # type: ignore[assignment]
    alias = _ALIAS.fullmatch(base)
    if base in METRICS:
        spec = METRICS[base]
        column, default = spec.metric, spec.sense
        label = f"{spec.label} ({spec.unit})" if spec.unit else spec.label
    elif alias and alias.group("m") in _MANEUVER_OF_SHORT:
        maneuver = _MANEUVER_OF_SHORT[alias.group("m")]
        suffix, what, unit, _ = FIGURES[alias.group("f")]
        pct = alias.group("p")
        column = f"{maneuver}_{suffix}" + (f"_{pct}" if pct else "")
        default = "min"
        label = f"{maneuver.replace('_', ' ')} {what}{f' {pct}' if pct else ''} ({unit})"
    else:
        column, default, label = base, "min", base
    known = sweep.numeric()
    if column not in known:
        what = (f"no numeric column {column!r}" if column == base
                else f"no column {column!r} (for {base})")
        raise RequestError(f"{flag} {name}: {sweep.path} has {what}; known: "
                           f"{', '.join(known) or 'none'}")
    sense = sense or default
    if m and sense != default:
        label = f"{label}, {sense}imised"
    return Axis(name, column, sense, label)


def null_meaning(column: str) -> str:
    """What a null in a column means, for the "left out" line: ``never rose in
    roll_step`` for a rise time, ``no price`` for a static column."""
    for suffix, _, _, meaning in FIGURES.values():
        m = re.fullmatch(rf"(.+)_{suffix}(?:_(p\d\d))?", column)
        if meaning and m and m.group(1) in MANEUVERS:
            return f"{meaning} in {m.group(1)}" + (f" ({m.group(2)})" if m.group(2) else "")
    return f"no {column}"


@dataclass(frozen=True)
class LeftOut:
    """Rows not on the plot, each counted once under its first reason (in this order)."""

    other_actuators: int
    errors: int
    cannot_hover: int
    missing: dict[str, int]  # per column: null or not a finite number

    def to_dict(self) -> dict[str, Any]:
        return {"other_actuators": self.other_actuators, "errors": self.errors,
                "cannot_hover": self.cannot_hover, "missing": dict(self.missing)}

    def text(self) -> str:
        """``left out: 3 errors, 12 cannot hover, 40 never rose in roll_step``."""
        counts = [(self.other_actuators, "of other actuator counts"),
                  (self.errors, "error" if self.errors == 1 else "errors"),
                  (self.cannot_hover, "cannot hover"),
                  *((n, null_meaning(c)) for c, n in self.missing.items())]
        return "left out: " + (", ".join(f"{n} {what}" for n, what in counts if n) or "none")


def usable_rows(sweep: SweepFile, table: pa.Table, columns: list[str],
                actuators: list[int] | None = None) -> tuple[np.ndarray, LeftOut]:
    """Rows that flew (no ``error``), can hover and have a finite number in every one of
    ``columns``; with ``actuators``, only rows of those counts. And why the others not."""
    keep = np.ones(table.num_rows, bool)
    other = 0
    if actuators is not None:
        n = pc.fill_null(table.column("actuators"), -1).to_numpy()
        inside = np.isin(n, actuators)
        other = int((~inside).sum())
        keep &= inside

    def drop(mask: np.ndarray) -> int:
        hit = keep & mask
        keep[hit] = False
        return int(hit.sum())

    # pyarrow.compute makes its functions at import; its stubs do not list is_valid
    valid = pc.is_valid(table.column("error"))  # pyright: ignore[reportAttributeAccessIssue]
    errors = drop(valid.to_numpy(zero_copy_only=False))
    hover = pc.fill_null(table.column("can_hover"), False).to_numpy(zero_copy_only=False)
    cannot = drop(~hover.astype(bool))
    missing = {c: drop(~np.isfinite(sweep.floats(table, c))) for c in dict.fromkeys(columns)}
    return keep, LeftOut(other, errors, cannot, missing)


@dataclass(frozen=True)
class SweepFront:
    """The non-dominated rows of a sweep file in two columns, and what was left out."""

    x: Axis
    y: Axis
    front: list[dict[str, Any]]  # in increasing x cost
    rows: int
    considered: int
    left_out: LeftOut
    actuators: list[int]
    cloud: tuple[np.ndarray, np.ndarray]  # every considered row's (x, y), file order


def front(sweep: SweepFile, x_name: str, y_name: str,
          actuators: list[int] | None = None) -> SweepFront:
    """The exact front of two columns over the rows that flew and hover
    (``optimizer.solve.pareto.enumerate_front``: equal points keep the first row of the file)."""
    x, y = sweep.axis(x_name, "--x"), sweep.axis(y_name, "--y")
    if x.column == y.column:
        raise RequestError(f"--x {x_name} and --y {y_name} are both the column {x.column}; "
                           "give two different ones")
    table = sweep.read([x.column, y.column, "actuators", *FLAGS])
    keep, left = usable_rows(sweep, table, [x.column, y.column], actuators)
    vx, vy = sweep.floats(table, x.column), sweep.floats(table, y.column)
    positions = enumerate_front(x.cost(vx), y.cost(vy), keep).indices
    wanted = [*DESIGN_KEYS, *STATIC_KEYS, x.column, y.column]
    counts = pc.fill_null(table.column("actuators"), -1).to_numpy()[keep]
    return SweepFront(x, y, sweep.take(positions, wanted), sweep.rows, int(keep.sum()), left,
                      sorted(int(n) for n in np.unique(counts)), (vx[keep], vy[keep]))
