"""Every bench's stored constants of one actuator, compared (``rotorbench
compare-benches``, the web view's ``/benches``).

Why: a lab with several benches asks whether they measure the same motor the same way.
The constants store keeps, for each fit, the run it came from; the run names its bench
(``--bench``, else the rig file's name, else the host: ``bench.store.lab_publish.bench_name``,
what the run list shows). Per bench the newest fit of each kind is taken, as the store's
own current constants are (a newer fit replaces an older one; a bench recalibrated since
is judged as it measures now). Each constant's uncertainty is read by
``bench.store.stored_uncertainty.stored_budget``; the maths is
``analysis.metrology.interlab``.

The lab catalog keeps every fit, so it holds every bench's. A folder store keeps one row
per actuator and kind, whichever bench fitted it last: it holds a second bench's only
for another ESC, mode or battery, which is not compared (like with like).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from analysis.metrology.constant_budgets import BUDGETED
from analysis.metrology.interlab import ConstantComparison, Participant, compare_constant
from bench.errors import RigError
from bench.store.constants_fit import UNCERTAINTY
from bench.store.json_values import finite_number
from bench.store.run_summary import RunFilter
from bench.store.stored_uncertainty import stored_budget

__all__ = ["COMPARED", "BenchComparison", "BenchSource", "NothingToCompare",
           "compare_benches"]


class NothingToCompare(RigError):
    """The request names no actuator two benches measured alike: the asker's to change
    (a command exits 2, the web view answers 422), not a fault of the store."""


def _poly(i: int) -> Callable[[Mapping[str, Any]], Any]:
    def coefficient(data: Mapping[str, Any]) -> Any:
        coef = data.get("thrust_poly_w")
        return coef[i] if isinstance(coef, list) and len(coef) > i else None
    return coefficient


def _key(name: str) -> Callable[[Mapping[str, Any]], Any]:
    return lambda data: data.get(name)


#: the constants compared: (data key, kind of fit, unit, how the row gives its value)
COMPARED: tuple[tuple[str, str, str, Callable[[Mapping[str, Any]], Any]], ...] = tuple(
    (c.key, c.run, c.unit,
     _poly(int(c.key.rsplit("_", 1)[1])) if c.key.startswith("thrust_poly_w_") else _key(c.key))
    for c in BUDGETED)
ACTUATOR = ("motor", "propeller", "esc", "esc_mode", "battery")


@dataclass(frozen=True)
class BenchSource:
    """Where one bench's constants came from: the run and fit time of each kind."""

    bench: str
    runs: dict[str, str]  # kind -> run id
    fitted_utc: dict[str, str]  # kind -> when it was fitted
    calibrations: tuple[str, ...] = ()  # the calibration records its constants read through

    def as_dict(self) -> dict[str, Any]:
        return {"bench": self.bench, "runs": self.runs, "fitted_utc": self.fitted_utc,
                "calibrations": list(self.calibrations)}


@dataclass(frozen=True)
class BenchComparison:
    """One actuator's constants on every bench that measured it, and every pair's E_n."""

    store: str
    actuator: dict[str, str]
    benches: tuple[BenchSource, ...]
    constants: tuple[ConstantComparison, ...]
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def flagged(self) -> list[tuple[str, str, str, float]]:
        """(constant, bench, bench, E_n) of every pair with |E_n| > 1."""
        return [(c.name, p.bench_a, p.bench_b, p.e_n) for c in self.constants
                for p in c.flagged if p.e_n is not None]

    def as_dict(self) -> dict[str, Any]:
        return {"store": self.store, "actuator": self.actuator,
                "benches": [b.as_dict() for b in self.benches],
                "constants": [c.as_dict() for c in self.constants],
                "flagged": [{"constant": c, "a": a, "b": b, "e_n": e}
                            for c, a, b, e in self.flagged],
                "notes": list(self.notes)}


def compare_benches(store: Any, motor: str, propeller: str, *, esc: str | None = None,
                    esc_mode: str | None = None, battery: str | None = None
                    ) -> BenchComparison:
    """The comparison of every bench in ``store`` that measured this actuator;
    ``NothingToCompare`` (one line) when there is nothing to compare."""
    where = store.describe()
    rows = store.constants(history=True)
    if not rows:
        raise NothingToCompare(f"{where}: no constants stored (store some with "
                               "`rotorbench constants --add RUN`)")
    wanted = {"motor": motor, "propeller": propeller, "esc": esc, "esc_mode": esc_mode,
              "battery": battery}
    for name, value in wanted.items():
        if value is None:
            continue
        have = sorted({getattr(r, name) for r in rows})
        rows = [r for r in rows if getattr(r, name) == value]
        if not rows:
            raise NothingToCompare(f"--{name.replace('_', '-')} {value}: no constants of it "
                                   f"in {where} (stored: {', '.join(have[:12]) or 'none'})")
    combos = sorted({(r.esc, r.esc_mode, r.battery) for r in rows})
    if len(combos) > 1:
        raise NothingToCompare(f"{motor} / {propeller}: measured with several ESCs, modes "
                               f"or batteries ({'; '.join(' '.join(c) for c in combos)}); "
                               "benches are compared like with like: name one with --esc, "
                               "--esc-mode, --battery")
    notes: list[str] = []
    newest = _newest_per_bench(rows, _bench_of_runs(store, motor, propeller), notes)
    if len(newest) < 2:
        only = f"only bench {next(iter(newest))}" if newest else "no bench"
        raise NothingToCompare(f"nothing to compare: {only} measured {motor} / {propeller} "
                               f"in {where} (a comparison needs two benches or more)")
    benches = sorted(newest)
    constants = []
    for name, kind, unit, value_of in COMPARED:
        parts = []
        for bench in benches:
            row = newest[bench].get(kind)
            x = None if row is None else finite_number(value_of(row.data))
            if row is not None and x is not None:
                parts.append(Participant(bench, x, stored_budget(name, x, unit, row.data),
                                         row.run_id))
        if len(parts) >= 2:
            constants.append(compare_constant(name, unit, parts))
    if not constants:
        raise NothingToCompare(f"nothing to compare: benches {', '.join(benches)} share no "
                               f"constant of {motor} / {propeller} in {where}")
    esc_, mode, batt = combos[0]
    return BenchComparison(
        where, {"motor": motor, "propeller": propeller, "esc": esc_, "esc_mode": mode,
                "battery": batt},
        tuple(BenchSource(b, {k: r.run_id for k, r in newest[b].items()},
                          {k: r.fitted_utc for k, r in newest[b].items()},
                          _calibrations(newest[b].values())) for b in benches),
        tuple(constants), tuple(notes))


def _calibrations(rows: Iterable[Any]) -> tuple[str, ...]:
    """The calibration records the rows' stored budgets name (none for older rows)."""
    ids: set[str] = set()
    for row in rows:
        entries = row.data.get(UNCERTAINTY)
        for entry in entries.values() if isinstance(entries, Mapping) else ():
            cals = entry.get("calibrations") if isinstance(entry, Mapping) else None
            ids.update(str(c) for c in cals or () if c)
    return tuple(sorted(ids))


def _bench_of_runs(store: Any, motor: str, propeller: str) -> dict[str, str]:
    """run id -> bench, of the store's runs of this motor and propeller."""
    runs = store.list_runs(RunFilter(motor=motor, propeller=propeller))
    return {r.run_id: r.bench for r in runs if r.bench}


def _newest_per_bench(rows: Sequence[Any], bench_of: Mapping[str, str], notes: list[str]
                      ) -> dict[str, dict[str, Any]]:
    """bench -> kind -> its newest row (rows come oldest first within a kind: the later
    of two fitted in the same second wins)."""
    out: dict[str, dict[str, Any]] = {}
    for row in rows:
        bench = bench_of.get(row.run_id) or _bench_from_folder(row.run_path)
        if bench is None:
            notes.append(f"{row.kind} constants of run {row.run_id}: the run is not in the "
                         "store, its bench unknown: left out")
            continue
        slot = out.setdefault(bench, {})
        prev = slot.get(row.kind)
        if prev is None or row.fitted_utc >= prev.fitted_utc:
            slot[row.kind] = row
    return out


def _bench_from_folder(run_path: str) -> str | None:
    """The bench of a run fitted from a folder outside the store, from its run.json."""
    from bench.store.lab_publish import bench_name

    folder = Path(run_path)
    if not run_path or "://" in run_path or not (folder / "run.json").is_file():
        return None
    from analysis.errors import LogError
    from analysis.run_paths import read_run_json

    try:
        return bench_name(read_run_json(folder))
    except LogError:
        return None
