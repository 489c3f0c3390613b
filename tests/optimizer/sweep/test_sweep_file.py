"""``pareto --from SWEEP.parquet``: the exact front of two columns of a closed-loop sweep
file (brute-force dominance on random rows with ties and nulls), the same front as the MILP
on a file of the catalog's designs, the CLI's JSON and text, and bad files and options."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from bench.cli import main
from optimizer.solve.pareto import RTOL, enumerate_front
from optimizer.sweep.sweep_file import SPEC_KEY, front, open_sweep
from tests.conftest import run_bad

SPEC = {"catalog": "thesis-e", "options": {"payload_kg": 0.0}, "maneuvers": ["roll_step"]}


def write_sweep(path: Path, rows: pd.DataFrame | list[dict[str, Any]],
                spec: dict[str, Any] | None = None, row_group_size: int | None = None) -> Path:
    """A sweep file as ``fly --sweep --out`` writes it: one row per design, the spec as
    the ``rotorbench_sweep`` metadata."""
    table = pa.Table.from_pandas(pd.DataFrame(rows), preserve_index=False)
    meta = {**(table.schema.metadata or {}), SPEC_KEY: json.dumps(spec or SPEC).encode()}
    pq.write_table(table.replace_schema_metadata(meta), path, row_group_size=row_group_size)
    return path


def random_rows(seed: int) -> pd.DataFrame:
    """Rows with exact ties (integer values), nulls, errors and designs that cannot hover."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 250))
    ints = seed % 2 == 0
    a = rng.integers(0, 8, n).astype(float) if ints else rng.random(n)
    b = rng.integers(0, 8, n).astype(float) if seed % 3 else rng.random(n)
    a[rng.random(n) < 0.1] = np.nan
    b[rng.random(n) < 0.1] = np.nan
    return pd.DataFrame({
        "actuators": rng.choice([4, 6, 8], n), "propeller": [f"P{i}" for i in range(n)],
        "motor": "M1", "battery": "B1", "series": 1, "parallel": 1,
        "design_id": [f"d{i}" for i in range(n)],
        "price": rng.integers(100, 110, n).astype(float),
        "can_hover": rng.random(n) < 0.85,
        "roll_step_rise_time_ms": pd.array(np.where(np.isnan(a), None, a), dtype="Float64"),
        "score": b,
        "error": [("boom" if e else None) for e in rng.random(n) < 0.07],
    })


def brute_force(x: np.ndarray, y: np.ndarray) -> set[tuple[float, float]]:
    """The non-dominated points (both minimised), O(n^2)."""
    return {(x[i], y[i]) for i in range(x.size)
            if not np.any((x <= x[i]) & (y <= y[i]) & ((x < x[i]) | (y < y[i])))}


@pytest.mark.parametrize("seed", range(24))
def test_front_is_exact_on_random_rows(tmp_path: Path, seed: int) -> None:
    rows = random_rows(seed)
    path = write_sweep(tmp_path / "s.parquet", rows, row_group_size=int(seed % 5 * 9 + 1))
    x_name, y_name = ("roll-rise", "max:score") if seed % 4 else ("max:price", "score")
    x_col, sx = ("roll_step_rise_time_ms", 1) if seed % 4 else ("price", -1)
    y_col, sy = ("score", -1) if seed % 4 else ("score", 1)
    res = front(open_sweep(path), x_name, y_name)

    x = rows[x_col].astype(float).to_numpy()
    y = rows[y_col].astype(float).to_numpy()
    flew = rows["error"].isna().to_numpy()
    hover = flew & rows["can_hover"].to_numpy()
    usable = hover & np.isfinite(x) & np.isfinite(y)
    got = [(sx * d[x_col], sy * d[y_col]) for d in res.front]
    assert set(got) == brute_force(sx * x[usable], sy * y[usable])
    assert len(got) == len(set(got))  # equal points: one kept
    assert [p[0] for p in got] == sorted(p[0] for p in got)  # in increasing x cost
    for d in res.front:  # ... the first row of the file at that point
        at = np.flatnonzero(usable & (sx * x == sx * d[x_col]) & (sy * y == sy * d[y_col]))
        assert d["design_id"] == f"d{at[0]}"
    left = res.left_out
    assert left.errors == int((~flew).sum())
    assert left.cannot_hover == int((flew & ~hover).sum())
    assert left.missing[x_col] == int((hover & ~np.isfinite(x)).sum())
    assert left.missing[y_col] == int((hover & np.isfinite(x) & ~np.isfinite(y)).sum())
    assert res.considered == int(usable.sum()) and res.rows == len(rows)
    assert res.cloud[0].size == res.considered


def _walk(ys: np.ndarray) -> list[int]:
    """The sequential tolerance walk the vectorised one replaces (the former code)."""
    keep, best = [], np.inf
    for pos, v in enumerate(ys):
        if not np.isfinite(best) or v <= best - RTOL * max(abs(best), 1.0):
            keep.append(pos)
            best = v
    return keep


@pytest.mark.parametrize("seed", range(6))
def test_near_ties_count_as_one_point_as_in_the_milp_front(seed: int) -> None:
    """Points closer than RTOL are one point of the front (``optimizer.solve.pareto``); runs of
    such near-ties are walked in order, the rest vectorised: the same as the walk."""
    rng = np.random.default_rng(seed)
    base = np.sort(rng.random(40))[::-1] * 10.0 ** int(rng.integers(0, 4))
    # runs of up to 7 near-equal values 3e-10 apart: a run longer than RTOL keeps two
    ys = np.repeat(base, rng.integers(1, 8, base.size))
    ys = ys * (1 - np.cumsum(rng.choice([0.0, 3e-10, 2e-9], ys.size)))
    ys = np.unique(ys)[::-1]  # strictly falling, as the running minimum's drops are
    xs = np.arange(ys.size, dtype=float)
    walk = _walk(ys)
    assert enumerate_front(xs, ys, np.ones(ys.size, bool)).indices.tolist() == walk
    close = ys[1:] > ys[:-1] - RTOL * np.maximum(np.abs(ys[:-1]), 1.0)
    assert len(walk) > ys.size - close.sum()  # a run kept a second point: not a plain filter


def feasible_rows(n_list: tuple[int, ...] = (4, 6, 8)) -> list[dict[str, Any]]:
    """Every design of thesis-e that ``pareto`` may offer (hover margin 1.2), grid order,
    as a sweep row (rise time made up: only the static columns matter here)."""
    from bench.store.catalogs import load, with_min_thrust_to_weight
    from optimizer.model.design_model import evaluate_grid
    from optimizer.model.grid import METRIC_KEYS

    catalog = with_min_thrust_to_weight(load(None), 1.2)
    rows = []
    for n in n_list:
        grid = evaluate_grid(catalog, n)
        for i, j, k in np.argwhere(grid.feasible()):
            p, m, b = grid.propeller_ids[i], grid.motor_ids[j], grid.battery_ids[k]
            rows.append({"actuators": n, "propeller": p, "motor": m, "battery": b,
                         "series": None, "parallel": None, "design_id": f"{n}/{p}/{m}/{b}",
                         **{key: float(grid.metrics[key][i, j, k]) for key in METRIC_KEYS},
                         "thrust_to_weight": float(grid.extras["thrust_to_weight"][i, j, k]),
                         "can_hover": True,
                         "roll_step_rise_time_ms": 3.0 * grid.metrics["time_constant_ms"][
                             i, j, k], "error": None})
    return rows


def _json(capsys, *argv: str) -> dict[str, Any]:
    assert main([*argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


KEYS = ("actuators", "propeller", "motor", "battery")


@pytest.mark.parametrize(("x", "y", "actuators"), [
    ("flight-time", "time-constant", ()), ("price", "flight-time", ()),
    ("mass", "power", ("--actuators", "4")),
])
def test_static_front_of_the_file_is_the_milp_front(tmp_path: Path, capsys, x: str, y: str,
                                                    actuators: tuple[str, ...]) -> None:
    """A file of every design ``pareto`` solves over, in grid order: the same front, the
    same design at every point (ties: the MILP's lowest index = the first row)."""
    path = write_sweep(tmp_path / "all.parquet", feasible_rows())
    milp = _json(capsys, "pareto", "--x", x, "--y", y, *actuators)
    table = _json(capsys, "pareto", "--from", str(path), "--x", x, "--y", y, *actuators)
    assert [tuple(d[k] for k in KEYS) for d in table["front"]] == \
        [tuple(d[k] for k in KEYS) for d in milp["front"]]
    for key in ("x_key", "y_key", "x_label", "y_label"):
        assert table[key] == milp[key]
    assert table["actuators"] == milp["actuators"]


def test_cli_json_shape_text_and_plot(tmp_path: Path, capsys) -> None:
    rows = feasible_rows((4,))
    rows[0]["error"] = "integrator diverged"
    rows[1]["can_hover"], rows[2]["can_hover"] = False, False
    for r in rows[3:6]:
        r["roll_step_rise_time_ms"] = None
    path = write_sweep(tmp_path / "s.parquet", rows)
    png = tmp_path / "front.png"
    doc = _json(capsys, "pareto", "--from", str(path), "--x", "flight-time", "--y",
                "roll-rise", "--plot", str(png))
    assert {"x", "y", "x_key", "y_key", "x_label", "y_label", "front", "actuators", "method",
            "source", "catalog", "rows", "considered", "left_out", "sweep"} <= set(doc)
    assert (doc["x_key"], doc["y_key"]) == ("flight_time_min", "roll_step_rise_time_ms")
    assert (doc["x_sense"], doc["y_sense"]) == ("max", "min")
    assert doc["source"] == str(path) and doc["sweep"] == SPEC and doc["method"] == "sweep"
    assert doc["left_out"] == {"other_actuators": 0, "errors": 1, "cannot_hover": 2,
                               "missing": {"flight_time_min": 0, "roll_step_rise_time_ms": 3}}
    assert doc["considered"] == len(rows) - 6 and doc["rows"] == len(rows)
    first = doc["front"][0]
    assert list(first)[:7] == ["actuators", "propeller", "motor", "battery", "series",
                               "parallel", "design_id"]
    assert {"flight_time_min", "roll_step_rise_time_ms", "price", "thrust_to_weight"} <= set(
        first)
    assert first["series"] is None
    assert png.stat().st_size > 1000
    assert main(["pareto", "--from", str(path), "--x", "flight-time", "--y", "roll-rise"]) == 0
    out = capsys.readouterr().out
    assert (f"{len(doc['front'])} points from {len(rows) - 6} of {len(rows)} rows; left out: "
            "1 error, 2 cannot hover, 3 never rose in roll_step") in " ".join(out.split())


@pytest.mark.parametrize(("margin", "said"), [
    ({"min_thrust_to_weight": None, "thesis_rules": True, "source": "--thesis-rules"},
     "thesis rules (the sweep's --thesis-rules): no hover margin, designs that cannot hover "
     "left out"),
    ({"min_thrust_to_weight": 2.0, "thesis_rules": True, "source": "--thesis-rules"},
     "the catalog's own min_thrust_to_weight 2 applied"),
    ({"min_thrust_to_weight": 1.2, "thesis_rules": False, "source": "default"},
     "hover margin (the sweep's, default): every design reaches full-throttle "
     "thrust-to-weight >= 1.2"),
])
def test_text_says_the_hover_margin_the_sweep_was_flown_under(tmp_path: Path, capsys,
                                                              margin, said) -> None:
    """A front of a ``fly --sweep --thesis-rules`` file may offer a design below the default
    margin (thesis-e's 8 x P1/M1/B3, thrust-to-weight 1.10): like ``pareto`` on a catalog,
    the text says which rule the designs were sized under (``--json`` has it in
    ``sweep.options.hover_margin``)."""
    spec = {**SPEC, "options": {**SPEC["options"], "hover_margin": margin}}
    path = write_sweep(tmp_path / "s.parquet", feasible_rows((4,)), spec)
    assert main(["pareto", "--from", str(path), "--x", "flight-time", "--y", "price"]) == 0
    assert said in " ".join(capsys.readouterr().out.split())
    plain = write_sweep(tmp_path / "plain.parquet", feasible_rows((4,)))  # no margin known
    assert main(["pareto", "--from", str(plain), "--x", "flight-time", "--y", "price"]) == 0
    assert "hover margin" not in capsys.readouterr().out


def test_axis_names(tmp_path: Path) -> None:
    """Objective names, closed-loop aliases (percentiles too), raw columns, max:/min:."""
    rows = [{"actuators": 4, "propeller": "P1", "motor": "M1", "battery": "B1",
             "can_hover": True, "error": None, "flight_time_min": 30.0,
             "altitude_step_settling_time_ms": 900.0, "roll_step_rise_time_ms_p95": 140.0,
             "gust_saturation_pct": 3.0, "score": 1}]
    sweep = open_sweep(write_sweep(tmp_path / "s.parquet", rows))
    cases = {
        "flight-time": ("flight_time_min", "max", "flight time (min)"),
        "min:flight-time": ("flight_time_min", "min", "flight time (min), minimised"),
        "altitude-settling": ("altitude_step_settling_time_ms", "min",
                              "altitude step settling time (ms)"),
        "roll-rise-p95": ("roll_step_rise_time_ms_p95", "min", "roll step rise time p95 (ms)"),
        "gust-saturation": ("gust_saturation_pct", "min", "gust saturation (%)"),
        "score": ("score", "min", "score"),
        "max:score": ("score", "max", "score, maximised"),
    }
    for name, (column, sense, label) in cases.items():
        axis = sweep.axis(name, "--x")
        assert (axis.column, axis.sense, axis.label) == (column, sense, label), name


def test_actuators_keeps_only_those_rows(tmp_path: Path, capsys) -> None:
    path = write_sweep(tmp_path / "all.parquet", feasible_rows())
    doc = _json(capsys, "pareto", "--from", str(path), "--actuators", "6", "8")
    assert doc["actuators"] == [6, 8]
    assert {d["actuators"] for d in doc["front"]} <= {6, 8}
    assert doc["left_out"]["other_actuators"] == sum(1 for r in feasible_rows((4,)))


def _bad_files(tmp_path: Path) -> dict[str, Path]:
    good = [{"actuators": 4, "propeller": "P1", "motor": "M1", "battery": "B1",
             "can_hover": True, "error": None, "flight_time_min": 30.0, "label": "x"}]
    text = tmp_path / "notes.parquet"
    text.write_text("not parquet\n")
    plain = tmp_path / "plain.parquet"
    pq.write_table(pa.Table.from_pylist(good), plain)
    badjson = tmp_path / "badjson.parquet"
    t = pa.Table.from_pylist(good)
    pq.write_table(t.replace_schema_metadata({SPEC_KEY: b"{nope"}), badjson)
    nocols = write_sweep(tmp_path / "nocols.parquet", [{"actuators": 4, "propeller": "P1"}])
    (tmp_path / "folder.parquet").mkdir()
    return {"missing": tmp_path / "none.parquet", "folder": tmp_path / "folder.parquet",
            "text": text, "plain": plain, "badjson": badjson, "nocols": nocols,
            "good": write_sweep(tmp_path / "good.parquet", good),
            "png": write_sweep(tmp_path / "named.png", good)}


@pytest.mark.parametrize(("which", "extra", "words"), [
    ("missing", (), "none.parquet: no such file"),
    ("folder", (), "is a folder; expected a sweep Parquet file"),
    ("text", (), "notes.parquet: not a Parquet file"),
    ("plain", (), "not a rotorbench sweep (no rotorbench_sweep metadata"),
    ("badjson", (), "rotorbench_sweep metadata is not JSON"),
    ("nocols", (), "not a complete sweep, no column motor, battery, can_hover, error"),
    ("good", ("--y", "roll-rise"),
     "--y roll-rise: {good} has no column 'roll_step_rise_time_ms' (for roll-rise); known: "
     "flight_time_min"),
    ("good", ("--y", "label"), "--y label: {good} has no numeric column 'label'; known: "
     "flight_time_min"),
    ("good", ("--y", "max:flight_time_min"), "are both the column flight_time_min"),
    ("good", ("--catalog", "thesis-d", "--method", "exact"),
     "--catalog, --method have no effect with --from"),
    ("good", ("--thesis-rules",), "--thesis-rules has no effect with --from"),
    ("good", ("--check", "--flyable"), "--check, --flyable have no effect with --from"),
    ("png", ("--plot", "{png}"), "named.png: is also an input"),
])
def test_bad_file_or_option_is_one_line_exit_2(tmp_path: Path, capsys, which: str,
                                               extra: tuple[str, ...], words: str) -> None:
    files = _bad_files(tmp_path)
    names = {"good": str(files["good"]), "png": str(files["png"])}
    argv = ["pareto", "--from", str(files[which]), "--x", "flight-time",
            *(a.format(**names) for a in extra)]
    if "--y" not in extra:
        argv += ["--y", "max:flight_time_min" if which in names else "time-constant"]
    line = run_bad(capsys, *argv)
    assert words.format(**names) in line


def test_closed_loop_names_without_from_say_so(capsys) -> None:
    line = run_bad(capsys, "pareto", "--x", "flight-time", "--y", "roll-rise")
    assert "--y roll-rise: expected one of flight-time" in line and "--from" in line


def test_a_maneuver_no_design_rose_in_leaves_every_row_out(tmp_path: Path, capsys) -> None:
    """A column of nulls only (Parquet's null type) is a column of the file, all missing:
    no front (exit 3), every row counted, rather than "no such column"."""
    rows = [{**r, "roll_step_rise_time_ms": None} for r in feasible_rows((4,))]
    path = write_sweep(tmp_path / "none_rose.parquet", rows)
    assert pq.read_schema(path).field("roll_step_rise_time_ms").type == pa.null()
    assert main(["pareto", "--from", str(path), "--y", "roll-rise", "--json"]) == 3
    doc = json.loads(capsys.readouterr().out)
    assert doc["front"] == [] and doc["considered"] == 0
    assert doc["left_out"]["missing"]["roll_step_rise_time_ms"] == len(rows)


@pytest.mark.parametrize("sense, style", [("max", "steps-pre"), ("min", "steps-post")])
def test_the_fronts_edge_steps_the_way_the_x_sense_reaches(tmp_path, monkeypatch, sense,
                                                           style) -> None:
    """A maximised x (flight time): between two front points only the next one reaches
    that x, so the edge holds the next point's y ("pre"); a minimised x the previous's."""
    import matplotlib.pyplot as plt

    from bench.figures import sizing_figures

    seen = {}
    monkeypatch.setattr(sizing_figures, "_save", lambda fig, path: seen.setdefault("fig", fig))
    doc = {"x_key": "a", "y_key": "b", "x_label": "a", "y_label": "b", "x_sense": sense,
           "catalog_name": "c", "actuators": [4],
           "front": [{"a": 1.0, "b": 1.0}, {"a": 2.0, "b": 3.0}]}
    sizing_figures.pareto_figure(doc, tmp_path / "f.png")
    ax = seen["fig"].axes[0]
    assert ax.lines[0].get_drawstyle() == style
    plt.close(seen["fig"])
