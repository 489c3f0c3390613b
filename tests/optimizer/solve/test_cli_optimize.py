"""``rotorbench optimize`` and ``rotorbench evaluate``: output, JSON keys, exit codes."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from bench.cli import main
from optimizer.solve.selection import ENTRY_KEYS
from tests.conftest import CATALOGS, SIZINGLAB


def run_json(capsys, *argv: str) -> tuple[int, dict]:
    code = main([*argv, "--json"])
    return code, json.loads(capsys.readouterr().out)


def test_optimize_json_keys_and_best(capsys, fixtures_dir) -> None:
    cat = str(CATALOGS / "thesis-e")
    code, out = run_json(capsys, "optimize", "--catalog", cat, "--objective", "flight-time")
    assert code == 0
    assert [d["actuators"] for d in out["designs"]] == [4, 6, 8]
    for entry in out["designs"]:
        assert list(entry)[: len(ENTRY_KEYS)] == list(ENTRY_KEYS)
        assert entry["feasible"] and entry["status"] == "optimal" and entry["mip_gap"] == 0
    best = out["best"]
    assert best["flight_time_min"] == max(d["flight_time_min"] for d in out["designs"])
    assert {best["propeller"], best["battery"]} <= {"P1", "P2", "P3", "P4", "B1", "B2", "B3", "B4"}


def test_optimize_default_catalog_and_table(capsys) -> None:
    assert main(["optimize", "--payload-kg", "1.5", "--actuators", "4", "8"]) == 0
    out = capsys.readouterr().out
    assert "Flight time (min)" in out and "8 * best" in out and "Number of actuators" in out


def test_methods_agree_on_the_cli(capsys, fixtures_dir) -> None:
    cat = str(CATALOGS / "thesis-d")
    args = ["optimize", "--catalog", cat, "--objective", "time-constant", "--payload-kg", "0.5"]
    _, a = run_json(capsys, *args, "--method", "milp")
    _, b = run_json(capsys, *args, "--method", "exact")
    ids = [(d["propeller"], d["motor"], d["battery"]) for d in a["designs"]]
    assert ids == [(d["propeller"], d["motor"], d["battery"]) for d in b["designs"]]


def test_partly_infeasible_exits_0_with_reason(capsys) -> None:
    code, out = run_json(capsys, "optimize", "--min-flight-time-min", "58")
    assert code == 0
    eight = out["designs"][2]
    assert eight["feasible"] is False and eight["propeller"] is None
    assert "flight time (required minimum)" in eight["reason"] and "short by" in eight["reason"]
    assert out["best"]["actuators"] in (4, 6)


def test_nothing_feasible_exits_3(capsys) -> None:
    code, out = run_json(capsys, "optimize", "--max-time-constant-ms", "5")
    assert code == 3
    assert out["best"] is None
    assert all("time constant (required maximum)" in d["reason"] for d in out["designs"])
    assert main(["optimize", "--payload-kg", "40", "--actuators", "4"]) == 3
    assert "No feasible design" in capsys.readouterr().out


def test_weighted_objective(capsys) -> None:
    code, out = run_json(
        capsys, "optimize", "--objective", "weighted", "--weights", "flight-time=0.5,price=0.5"
    )
    assert code == 0 and out["objective"].startswith("weighted(")
    assert main(["optimize", "--objective", "weighted"]) == 2
    assert "needs --weights" in capsys.readouterr().err


def test_evaluate_reports_the_same_keys(capsys) -> None:
    argv = ["evaluate", "--actuators", "4", "--propeller", "P4", "--motor", "M3"]
    code, out = run_json(capsys, *argv, "--battery", "B3")
    assert code == 0
    assert set(ENTRY_KEYS) <= set(out)
    assert out["feasible"] is True and "reason" not in out
    assert out["flight_time_min"] == pytest.approx(62.5, abs=0.05)  # Table E.8, 4 actuators
    assert main([*argv, "--battery", "B3", "--payload-kg", "20"]) == 0
    assert "VIOLATED" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, message",
    [
        (
            [
                "evaluate",
                "--actuators",
                "4",
                "--propeller",
                "P9",
                "--motor",
                "M1",
                "--battery",
                "B1",
            ],
            "unknown propeller id 'P9'",
        ),
        (["optimize", "--catalog", "/nonexistent/catalog"], "/nonexistent/catalog"),
        (["optimize", "--actuators", "2"], "actuators"),
        (["optimize", "--objective", "weighted", "--weights", "speed=1"], "unknown metric"),
        (["optimize", "--payload-kg", "-1"], "payload"),
    ],
)
def test_bad_input_exit_2_one_line(capsys, argv, message) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]


def test_bad_catalog_subprocess_no_traceback(tmp_path, fixtures_dir) -> None:
    bad = tmp_path / "cat"
    bad.mkdir()
    for name in ("propellers.csv", "motors.csv", "batteries.csv"):
        text = (CATALOGS / "thesis-e" / name).read_text()
        if name == "motors.csv":
            text = text.replace(",0.222,", ",abc,")
        (bad / name).write_text(text)
    proc = subprocess.run(
        [sys.executable, "-m", "bench.cli", "optimize", "--catalog", str(bad)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert "motors.csv" in proc.stderr and "resistance_ohm" in proc.stderr


def test_paper_e_cases(capsys) -> None:
    code = main(["optimize", "--paper-e-cases", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    assert [c["case"] for c in out["cases"]] == ["I", "II", "III"]
    assert [c["payload_kg"] for c in out["cases"]] == [0.0, 1.5, 0.0]
    assert [c["objective"] for c in out["cases"]] == ["flight-time", "flight-time", "time-constant"]
    # Test Case I: the thesis' flight times 62.5 / 60.0 / 55.5 min (Table E.8)
    flights = [d["flight_time_min"] for d in out["cases"][0]["designs"]]
    assert flights == pytest.approx([62.5, 60.0, 55.5], abs=0.1)
    assert main(["optimize", "--paper-e-cases"]) == 0
    text = capsys.readouterr().out
    assert "Test Case III" in text and "Table E.10" in text


def test_import_sizinglab_command(capsys, shared_data, tmp_path) -> None:
    source = SIZINGLAB
    out = tmp_path / "sl"
    assert main(["import-sizinglab", "--source", str(source), "--out", str(out)]) == 0
    assert "204 motors" in capsys.readouterr().out
    assert main(["import-sizinglab", "--source", str(source), "--out", str(out)]) == 2
    assert (
        main(["import-sizinglab", "--source", str(tmp_path / "none"), "--out", str(tmp_path / "x")])
        == 2
    )
    assert not (tmp_path / "x").exists()


def test_method_thesis_is_evaluated_exactly(capsys) -> None:
    code, out = run_json(capsys, "optimize", "--method", "thesis", "--actuators", "4")
    assert code == 0
    entry = out["designs"][0]
    assert entry["method"] == "thesis" and entry["feasible"]
    assert "linearised" in entry and entry["shortfall_vs_exact"] is not None
    # Test Case I, 4 actuators: the thesis formulation reaches the exact flight time optimum
    _, exact = run_json(capsys, "optimize", "--method", "exact", "--actuators", "4")
    assert entry["flight_time_min"] == pytest.approx(exact["designs"][0]["flight_time_min"])


def test_a_chosen_design_that_cannot_hover_is_said_so(capsys, fixtures_dir) -> None:
    """The exact Case III optimum with 4 actuators (P1/M1/B3; Table E.10 prints B1) needs
    4994 rpm; M1 reaches 4279 rpm on 12 V. The thesis' limits (--thesis-rules) accept it;
    optimize says so, and --flyable removes it."""
    cat = str(CATALOGS / "thesis-e")
    code, doc = run_json(capsys, "optimize", "--catalog", cat, "--actuators", "4",
                         "--objective", "time-constant", "--thesis-rules")
    assert code == 0 and doc["best"]["propeller"] == "P1" and doc["best"]["motor"] == "M1"
    [warning] = doc["warnings"]
    assert "P1/M1/B3: cannot hover: thrust-to-weight 0.73" in warning
    assert "needs 4994 rpm" in warning and "4279 rpm" in warning
    code, doc = run_json(capsys, "optimize", "--catalog", cat, "--actuators", "4",
                         "--thesis-rules")
    assert doc["warnings"] == []  # Case I's P4/M1/B3 hovers at 74 % throttle
    code, doc = run_json(capsys, "optimize", "--catalog", cat, "--actuators", "4",
                         "--objective", "time-constant", "--flyable", "--thesis-rules")
    assert code == 0 and doc["warnings"] == []
    assert (doc["best"]["propeller"], doc["best"]["motor"]) != ("P1", "M1")


def test_paper_e_cases_warn_per_case(capsys) -> None:
    assert main(["optimize", "--paper-e-cases", "--json"]) == 0
    cases = {c["case"]: c for c in json.loads(capsys.readouterr().out)["cases"]}
    assert all("warnings" in c for c in cases.values())
    warned = {(c, w.split(":")[0]) for c, case in cases.items() for w in case["warnings"]}
    # Case I hovers; Case II's 4-actuator tie pick M1 and Case III's B3 picks do not
    assert not any(c == "I" for c, _ in warned)
    assert any("P1/M1/B3" in who for _, who in warned)
