"""The demo end to end on one motor x propeller combination (the full demo runs all 12)."""

from __future__ import annotations

import json

from bench.cli import main
from bench.store.constants_store import ConstantsStore


def test_demo_one_combination(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--combos", "1", "--repeats", "2"]) == 0
    printed = capsys.readouterr().out
    assert "Table C.1 on P1-M1" in printed and "Paper E test cases" in printed
    assert {p.name for p in (out / "tables").iterdir()} == {
        "table_c1.csv", "designs.csv", "table_e11.csv", "table_e13.csv", "table_e14.csv",
        "measured_vs_model.csv"}
    figs = {p.name for p in (out / "figures").iterdir()}
    assert {"steps_three_modes.png", "static_P1-M1.png", "validation_diode.png"} <= figs
    rows = ConstantsStore(out / "runs").rows()
    assert sorted((r.key.esc_mode, r.kind) for r in rows) == [
        (mode, kind) for mode in ("complementary", "diode", "stock")
        for kind in ("static", "step")]
    summary = json.loads((out / "demo.json").read_text(encoding="utf-8"))
    tc1 = summary["table_c1"]
    # the Table C.1 pattern on this actuator too: diode and stock fall much slower
    for mode in ("diode", "stock"):
        assert tc1[mode]["tau_down_ms"] > 1.5 * tc1["complementary"]["tau_down_ms"]
    measured = [d for d in summary["designs"] if d["constants"] == "measured"]
    assert len(measured) == 9 and any(d["measured metrics"] != "datasheet" for d in measured)
    assert not any(p.name.startswith(".") for p in tmp_path.iterdir())
    # the design tables offer what `optimize` offers: designs that hover with margin;
    # under the thesis' rules Case III would pick P1/M1/B3, which cannot hover
    assert summary["hover_margin"]["min_thrust_to_weight"] == 1.2
    assert "hover margin: every design reaches full-throttle thrust-to-weight >= 1.2" in printed
    [case3] = [c for c in summary["cases"] if c["case"] == "III" and c["constants"] == "model"]
    for rules, equal in (([], True), (["--thesis-rules"], False)):
        assert main(["optimize", "--catalog", "thesis-e", "--objective", "time-constant",
                     "--json", *rules]) == 0
        picks = json.loads(capsys.readouterr().out)["designs"]
        ids = [[(d["actuators"], d["propeller"], d["motor"], d["battery"]) for d in ds]
               for ds in (picks, case3["designs"])]
        assert (ids[0] == ids[1]) is equal, rules
    # the web view over the demo's output shows every run, its fits and a comparison;
    # the same demo run, to keep the suite short
    from fastapi.testclient import TestClient

    from bench.serve.app import create_app
    from bench.store.stores import open_store

    recorded = sorted(p.parent.name for p in (out / "runs").glob("*/run.json"))
    with TestClient(create_app(open_store(str(out / "runs")))) as web:
        listed = web.get("/api/runs", params={"limit": 1000}).json()
        assert sorted(r["run_id"] for r in listed) == recorded and len(recorded) >= 5
        for rid in recorded:
            fits = web.get(f"/api/runs/{rid}/fits").json()
            assert "step" in fits or "static" in fits, (rid, fits)
            assert web.get(f"/runs/{rid}").status_code == 200
        steps = [r["run_id"] for r in listed if r["sequence"] == "step1"][:2]
        both = web.get("/api/compare", params={"runs": ",".join(steps)}).json()
        assert [s["run_id"] for s in both["steps"]] == steps
        assert all(s.get("up_edges", 0) >= 2 for s in both["steps"])
        assert len(web.get("/api/constants").json()) == len(rows)
