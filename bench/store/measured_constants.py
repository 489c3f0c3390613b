"""The constants store as the optimizer's measured overrides: the second half of the
constants stage (the first, run -> store, is ``bench.store.constants_fit``).

``load_measured`` turns the rows of ``<root>/constants.sqlite`` into
``optimizer.model.measured.MeasuredActuator`` overrides, one per (propeller, motor, ESC mode).
``load_measured_set`` picks those of one catalog and one ESC mode as a ``MeasuredSet``,
which builds the optimizer's grids with them and names each design's sources. Library
code rather than CLI code: ``optimize``, ``evaluate``, ``fly``, the demo and the docs'
figure scripts all read the store the same way.

A store root is the folder the ``constants`` command and the bench commands write to
(default ``./runs``, where ``constants.sqlite`` sits beside ``runs.sqlite``); a
``rotorbench demo`` output folder works too (its store is in ``<out>/runs``).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.store.constants_store import STORE_NAME, ConstantsRow, ConstantsStore
from bench.store.json_values import finite_number
from optimizer.errors import RequestError

__all__ = ["MeasuredSet", "find_store", "is_measured", "load_measured", "load_measured_set"]


def load_measured(root: Path, catalog: str | None = None,
                  rows: list[ConstantsRow] | None = None) -> list[Any]:
    """The stored constants as ``optimizer.model.measured.MeasuredActuator`` overrides: the time
    constant is the mean of the rising and falling ones (Table E.13 compares that mean
    with the model), the current from the static curves; one per (propeller, motor, ESC
    mode), the most recent when several batteries/ESCs were measured. A mode without a
    sweep of its own takes the static curves of the same pair in another mode."""
    from optimizer.model.measured import MeasuredActuator

    by: dict[tuple[str, str, str], dict[str, ConstantsRow]] = {}
    for row in (rows if rows is not None else ConstantsStore(root).rows()):
        if catalog is not None and row.key.catalog != catalog:
            continue
        slot = by.setdefault((row.key.propeller, row.key.motor, row.key.esc_mode), {})
        prev = slot.get(row.kind)
        if prev is None or row.fitted_utc >= prev.fitted_utc:
            slot[row.kind] = row
    out = []
    for (prop, motor, mode), kinds in sorted(by.items()):
        step, static = kinds.get("step"), kinds.get("static")
        if static is None:  # steady curves hardly depend on the ESC mode: borrow one
            static = next((r["static"] for (p2, m2, _), r in sorted(by.items())
                           if (p2, m2) == (prop, motor) and "static" in r), None)
        tau = None
        if step is not None:
            tau = 0.5 * (step.data["tau_up_s"] + step.data["tau_down_s"])
        thrust = static.data.get("hover_thrust_n", []) if static is not None else []
        current = static.data.get("hover_current_a", []) if static is not None else []
        sources = ", ".join(f"{r.kind}: {r.run_id}" for r in (step, static) if r is not None)
        out.append(MeasuredActuator(
            propeller_id=prop, motor_id=motor, esc_mode=mode, time_constant_s=tau,
            hover_thrust_n=tuple(thrust), hover_current_a=tuple(current),
            supply_voltage_v=(static.data.get("voltage_v") if static is not None else None),
            max_thrust_n=(static.data.get("thrust_max_n") if static is not None and thrust
                          else None),
            source=sources, time_constant_source=step.run_id if step is not None else "",
            current_source=static.run_id if static is not None else "",
            **_flight_extras(step, static)))
    return out


#: MeasuredActuator field <- the kind of row and the key of its value in the row's data
#: (its spread's key: ``bench.store.constants_fit.STD_KEYS``)
_FLIGHT_FIELDS = (("tau_up_s", "step", "tau_up_s"), ("tau_down_s", "step", "tau_down_s"),
                  ("latency_s", "step", "latency_s"), ("k_f_n_s2", "static", "k_f_n_s2"),
                  ("k_m_nm_s2", "static", "k_q_nm_s2"))


def _flight_extras(step: ConstantsRow | None, static: ConstantsRow | None) -> dict[str, float]:
    """The flight model's optional constants (``MeasuredActuator`` tau_up_s ... k_m_nm_s2)
    where the store has them as positive finite numbers (latency >= 0), each with its
    uncertainty (``optimizer.model.measured.STD_OF``) where the store has that as a finite
    number >= 0: the standard uncertainty of its budget, else (an older row) the spread of
    one measurement; a store written before either was kept gives constants without any."""
    from bench.store.constants_fit import STD_KEYS, stored_entry
    from optimizer.model.measured import STD_OF

    rows = {"step": step, "static": static}
    out = {}
    for name, kind, key in _FLIGHT_FIELDS:
        row = rows[kind]
        if row is None:
            continue
        x = finite_number(row.data.get(key))
        if x is None or not (x > 0 or (name == "latency_s" and x >= 0)):
            continue
        out[name] = x
        # the constant's standard uncertainty where the store has its budget, else the
        # spread of one measurement (a row stored before budgets were kept)
        std = finite_number(stored_entry(row.data, key).get("u"))
        if std is None:
            std = finite_number(row.data.get(STD_KEYS[key]))
        if std is not None and std >= 0:
            out[STD_OF[name]] = std
    return out


@dataclass
class MeasuredSet:
    """The overrides of one store for one catalog and ESC mode."""

    store: Path | str  # a folder, or the lab catalog's (redacted) URL
    esc_mode: str
    overrides: list[Any]
    grids: dict[int, Any] = field(default_factory=dict)

    def build_grid(self, catalog: Any, n: int, payload_kg: float) -> Any:
        """``optimize(build_grid=...)``: the model grid with the overrides; kept for sources."""
        from optimizer.model.design_model import evaluate_grid

        grid = evaluate_grid(
            catalog, n, payload_kg, overrides=self.overrides, esc_mode=self.esc_mode
        )
        self.grids[n] = grid
        return grid

    def annotate(self, result: Any) -> None:
        """Add ``sources`` to every design of a selection result built by ``build_grid``."""
        from optimizer.model.design_model import design_sources

        for d in result.designs:
            grid = self.grids.get(d.actuators)
            d.extra["sources"] = (
                design_sources(grid, *d.index) if d.index is not None and grid is not None
                else None
            )

    def describe(self) -> dict[str, Any]:
        return {
            "store": str(self.store),
            "esc_mode": self.esc_mode,
            "actuators_measured": len([o for o in self.overrides if o.esc_mode == self.esc_mode]),
        }


def find_store(folder: Path) -> Path:
    """The folder holding constants.sqlite: ``folder`` itself or ``folder/runs``."""
    for root in (folder, folder / "runs"):
        if (root / STORE_NAME).is_file():
            return root
    raise RequestError(
        f"--measured {folder}: no {STORE_NAME} there or in {folder / 'runs'} "
        "(store constants with `rotorbench constants --add RUN` or run `rotorbench demo`)"
    )


def load_measured_set(folder: Path | str, catalog: Any, esc_mode: str | None,
                      rows: list[ConstantsRow] | None = None) -> MeasuredSet:
    """Overrides for ``catalog`` (matched by its folder name) and one ESC mode (None: the
    mode stored for the most combinations; a tie is refused)."""
    root = Path(folder) if rows is not None else find_store(Path(folder))  # rows: the lab's
    name = Path(str(catalog.source)).name
    overrides = load_measured(root, catalog=name, rows=rows)
    if not overrides:
        others = sorted({o.propeller_id + "/" + o.motor_id
                         for o in load_measured(root, rows=rows)})
        raise RequestError(
            f"--measured {root}: no constants stored for catalog {name!r} "
            f"(stored actuators of other rigs/catalogs: {', '.join(others[:8]) or 'none'})"
        )
    modes = Counter(o.esc_mode for o in overrides)
    if esc_mode is None:
        ranked = modes.most_common()
        if len(ranked) > 1 and ranked[0][1] == ranked[1][1]:
            raise RequestError(
                f"--measured {root}: ESC modes {', '.join(sorted(modes))} are stored for "
                "equally many combinations; choose one with --esc-mode"
            )
        esc_mode = ranked[0][0]
    elif esc_mode not in modes:
        raise RequestError(
            f"--esc-mode {esc_mode}: not in {root} (stored: {', '.join(sorted(modes))})"
        )
    return MeasuredSet(root, str(esc_mode), overrides)


def is_measured(sources: dict[str, str] | None, key: str) -> bool:
    """Whether a design's metric ``key`` came from the store (its ``sources`` say so)."""
    return bool(sources) and str(sources.get(key, "")).startswith("measured")
