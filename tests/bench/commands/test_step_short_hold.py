"""The documented workflow `step --rig sim-thesis-e.toml --repeats 5`
then `fit` gave tau_up 164.7 ms but t63_up 160.8 ms (t63 is the model's 63 % point), with no
word that the 0.5 s hold is about 3 tau, too short for the response to settle."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.cli import main

RIGS = Path(__file__).resolve().parents[3] / "bench" / "data" / "rigs"


@pytest.fixture(scope="module")
def step_runs(tmp_path_factory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("runs")
    runs = {}
    for rig, hold in (("sim-thesis-e", "0.5"), ("sim-thesis-e", "1.0"), ("sim", "0.5")):
        before = set(out.glob("*-step1"))
        assert main(["step", "--rig", str(RIGS / f"{rig}.toml"), "--repeats", "2",
                     "--hold", hold, "--out", str(out)]) == 0
        (runs[f"{rig} {hold}"],) = set(out.glob("*-step1")) - before
    return runs


def _fit(capsys, run: Path) -> dict:
    capsys.readouterr()
    assert main(["fit", str(run), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("which", ["sim-thesis-e 0.5", "sim-thesis-e 1.0", "sim 0.5"])
def test_t63_is_the_fitted_models(step_runs, capsys, which: str) -> None:
    """t63 is read against the fitted final level, not the unsettled end of the window, so
    it is where the fitted model crosses 63.2 % (latency + tau for a first-order response;
    later here, where thrust is the square of the first-order speed)."""
    s = _fit(capsys, step_runs[which])
    for d in ("up", "down"):
        # 3 %: read against the window's unsettled end it was 11 % early
        assert s[f"rise_time_63_{d}_ms"] == pytest.approx(
            s[f"model_rise_time_63_{d}_ms"], rel=0.03)
    assert s["model_rise_time_63_up_ms"] > s["latency_up_ms"] + s["tau_up_ms"] + 3.0


def test_a_hold_shorter_than_4_tau_gets_a_note(step_runs, capsys, tmp_path) -> None:
    short = step_runs["sim-thesis-e 0.5"]
    s = _fit(capsys, short)
    (note,) = [n for n in s["notes"] if "has not settled" in n]
    assert note.startswith("levels held 0.5 s, less than 4 tau (tau_up 1")
    assert "hold each level at least 0.7 s (step --hold)" in note
    assert main(["fit", str(short)]) == 0
    assert "note: levels held 0.5 s, less than 4 tau" in capsys.readouterr().out
    assert main(["report", str(short), "--out", str(tmp_path / "rep")]) == 0
    assert f"note: {short.name}: levels held 0.5 s" in capsys.readouterr().out.replace("\n", "")
    report = json.loads((tmp_path / "rep" / "report.json").read_text())
    assert any("has not settled" in n for n in report["notes"])
    assert main(["constants", "--out", str(tmp_path / "store"), "--add", str(short)]) == 0
    assert "note: levels held 0.5 s, less than 4 tau" in capsys.readouterr().out
    from bench.store.constants_store import ConstantsStore

    (row,) = ConstantsStore(tmp_path / "store").rows()
    assert any("has not settled" in n for n in row.data["notes"])
    # settled holds: no note
    for which in ("sim-thesis-e 1.0", "sim 0.5"):
        assert not any("settled" in n for n in _fit(capsys, step_runs[which])["notes"])
