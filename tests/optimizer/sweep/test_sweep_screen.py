"""``optimize --max-roll-rise-ms T --from-sweep SWEEP.parquet``: the roll rise times read
from a sweep file give the design that flying candidates gives (thesis-e, N = 4, several T
and objectives); designs the file lacks are not screened and counted; a file that cannot
answer the question (other payload or model, no roll_step, other flight options) is
refused in one line."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pyarrow.parquet as pq
import pytest

from bench.cli import main
from tests.conftest import run_bad
from tests.optimizer.sweep.test_sweep_file import SPEC, write_sweep

DESIGN = ("actuators", "propeller", "motor", "battery")


@pytest.fixture(scope="module")
def flown_rows() -> list[dict[str, Any]]:
    """Every design ``optimize --actuators 4`` may offer, flown through ``roll_step`` by the
    scalar code of ``optimize --max-roll-rise-ms`` (``optimizer.flight.ranking``)."""
    from bench.store.catalogs import load, with_min_thrust_to_weight
    from optimizer.flight.design import feasible_indices
    from optimizer.flight.ranking import roll_step
    from optimizer.model.design_model import evaluate_grid
    from optimizer.model.grid import METRIC_KEYS

    catalog = with_min_thrust_to_weight(load(None), 1.2)
    grid = evaluate_grid(catalog, 4)
    rows = []
    for i, j, k in feasible_indices(grid):
        r = roll_step(catalog, grid, (i, j, k))
        rows.append({"actuators": 4, "propeller": r.propeller, "motor": r.motor,
                     "battery": r.battery, "series": None, "parallel": None,
                     "design_id": f"4/{r.propeller}/{r.motor}/{r.battery}",
                     **{key: float(grid.metrics[key][i, j, k]) for key in METRIC_KEYS},
                     "can_hover": not r.note, "roll_step_rise_time_ms": r.rise_time_ms,
                     "roll_step_overshoot_pct": r.overshoot_pct,
                     "roll_step_settling_time_ms": r.settling_time_ms,
                     "roll_step_saturation_pct": r.saturation_pct, "error": None})
    return rows


@pytest.fixture
def sweep(tmp_path: Path, flown_rows: list[dict[str, Any]]) -> Path:
    return write_sweep(tmp_path / "sweep.parquet", flown_rows)


def _optimize(capsys, *argv: str, code: int = 0) -> dict[str, Any]:
    assert main(["optimize", "--actuators", "4", *argv, "--json"]) == code
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize(("objective", "max_rise_ms"), [
    ("flight-time", "150"), ("flight-time", "300"), ("flight-time", "450"),
    ("price", "300"),  # many exact price ties: the MILP's pick, then catalog order
])
def test_same_design_as_flying(capsys, sweep: Path, objective: str,
                               max_rise_ms: str) -> None:
    flown = _optimize(capsys, "--objective", objective, "--max-roll-rise-ms", max_rise_ms)
    read = _optimize(capsys, "--objective", objective, "--max-roll-rise-ms", max_rise_ms,
                     "--from-sweep", str(sweep))
    assert [read["best"][k] for k in DESIGN] == [flown["best"][k] for k in DESIGN]
    info = read["best"]["flight"]
    assert info["roll_rise_ms"] == flown["best"]["flight"]["roll_rise_ms"]
    assert info["source"] == str(sweep) and info["flown"] == 0
    assert info["not_in_file"] == 0 and info["screened"] == 44  # 44 hover with margin


def test_designs_missing_from_the_file_are_not_screened(capsys, tmp_path: Path,
                                                        flown_rows: list[dict[str, Any]]
                                                        ) -> None:
    """Without the pick and its ties (thesis-e's motors differ in Kv only, so M1, M2, M3
    fly equally long), the next design that meets T in the file is chosen, and the
    missing ones are counted as possibly better."""
    argv = ("--max-roll-rise-ms", "300")
    best = _optimize(capsys, *argv)["best"]
    gone = [r for r in flown_rows
            if (r["propeller"], r["battery"]) == (best["propeller"], best["battery"])]
    rows = [r for r in flown_rows if r not in gone]
    meets = [r for r in rows if r["can_hover"] and r["roll_step_rise_time_ms"] is not None
             and r["roll_step_rise_time_ms"] <= 300]
    expected = max(meets, key=lambda r: r["flight_time_min"])  # ties: the first row
    path = write_sweep(tmp_path / "less.parquet", rows)
    read = _optimize(capsys, *argv, "--from-sweep", str(path))["best"]
    assert [read[k] for k in DESIGN] == [expected[k] for k in DESIGN]
    assert read["flight_time_min"] < best["flight_time_min"]
    assert read["flight"]["not_in_file"] == len(gone) == 3
    assert read["flight"]["not_in_file_better"] == 3
    assert main(["optimize", "--actuators", "4", *argv, "--from-sweep", str(path)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert f"from {path}: 41 screened, 3 not in the file, 3 of them better" in out


def test_no_design_meets_it_exit_3(capsys, sweep: Path) -> None:
    doc = _optimize(capsys, "--max-roll-rise-ms", "50", "--from-sweep", str(sweep), code=3)
    reason = doc["designs"][0]["reason"]
    assert f"no feasible design rises in roll within 50 ms in {sweep} (44 screened" in reason
    assert doc["designs"][0]["flight"]["not_in_file"] == 0


def test_other_actuator_counts_are_not_in_the_file(capsys, sweep: Path) -> None:
    doc = _optimize(capsys, "--max-roll-rise-ms", "300", "--from-sweep", str(sweep))
    six = _optimize(capsys, "--max-roll-rise-ms", "300", "--from-sweep", str(sweep),
                    "--actuators", "4", "6")["designs"][1]
    assert not six["feasible"] and "0 screened" in six["reason"]
    assert doc["best"]["actuators"] == 4


def _edited(tmp_path: Path, rows: list[dict[str, Any]], spec: dict[str, Any] | None = None,
            drop: str | None = None, **change: Any) -> str:
    """The file with row 5 changed, the columns starting with ``drop`` dropped."""
    rows = [{k: v for k, v in r.items() if not (drop and k.startswith(drop))} for r in rows]
    rows[5].update(change)
    return str(write_sweep(tmp_path / "edited.parquet", rows, spec))


@pytest.mark.parametrize(("edit", "extra", "words"), [
    ({"flight_time_min": 99.0}, (), "1 of its designs with 4 actuators have another "
     "flight_time_min than this catalog's model (e.g. P"),
    ({}, ("--payload-kg", "0.5"), "flown with a payload of 0 kg; this run asks for 0.5 kg"),
    ({"drop": "roll_step"}, (), "no roll_step_rise_time_ms column (maneuvers in the file: "
     "none); fly the sweep with roll_step"),
    ({"spec": {**SPEC, "options": {"payload_kg": 0.0, "drag_n_s_m": 0.2}}}, (),
     "flown with drag_n_s_m = 0.2; optimize flies the catalog's actuators with "
     "drag_n_s_m = 0.0"),
    ({"spec": {**SPEC, "options": {"layout": "plus"}}}, (), "flown with layout = 'plus'"),
    ({"spec": {**SPEC, "options": {"payload_kg": "none"}}}, (),
     "the spec's payload_kg 'none' is not a number"),
    ({"drop": "power_w"}, (), "no power_w column(s), needed to check the file"),
])
def test_a_file_that_cannot_answer_is_refused(capsys, tmp_path: Path,
                                              flown_rows: list[dict[str, Any]],
                                              edit: dict[str, Any], extra: tuple[str, ...],
                                              words: str) -> None:
    spec = edit.pop("spec", None)
    path = _edited(tmp_path, flown_rows, spec, **edit)
    line = run_bad(capsys, "optimize", "--actuators", "4", "--max-roll-rise-ms", "300",
                   "--from-sweep", path, *extra)
    assert words in line


def test_several_rows_per_design_are_refused(capsys, tmp_path: Path,
                                             flown_rows: list[dict[str, Any]]) -> None:
    path = write_sweep(tmp_path / "twice.parquet", flown_rows + flown_rows[:1])
    line = run_bad(capsys, "optimize", "--actuators", "4", "--max-roll-rise-ms", "300",
                   "--from-sweep", str(path))
    assert "several rows per design of 4 actuators" in line


def test_from_sweep_needs_the_limit(capsys, sweep: Path) -> None:
    line = run_bad(capsys, "optimize", "--from-sweep", str(sweep))
    assert "--from-sweep has no effect without --max-roll-rise-ms" in line
    line = run_bad(capsys, "optimize", "--paper-e-cases", "--from-sweep", str(sweep))
    assert "--from-sweep has no effect with --paper-e-cases" in line
    bad = sweep.with_name("plain.parquet")
    pq.write_table(pq.read_table(sweep).replace_schema_metadata({}), bad)
    line = run_bad(capsys, "optimize", "--max-roll-rise-ms", "300", "--from-sweep", str(bad))
    assert f"--from-sweep {bad}: not a rotorbench sweep" in line


def test_a_file_of_another_catalog_is_refused(capsys, tmp_path: Path,
                                              flown_rows: list[dict[str, Any]]) -> None:
    rows = [{**r, "propeller": "X" + r["propeller"]} for r in flown_rows]
    path = write_sweep(tmp_path / "other.parquet", rows)
    line = run_bad(capsys, "optimize", "--actuators", "4", "--max-roll-rise-ms", "300",
                   "--from-sweep", str(path))
    assert f"none of its {len(rows)} designs with 4 actuators is in this catalog (e.g. XP1/" \
        in line
