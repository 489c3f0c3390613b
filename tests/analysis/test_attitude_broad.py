"""The comparison table on BROAD trial 07 (real IMU, optical truth), as the CLI prints it.

Done-when of the orientation issue, on the shipped trial: the default filter's inclination
RMSE at most 1.25 x VQF's (6D) + 0.1°, its 9D heading at most 1.5 x VQF's (9D) + 0.5°,
Paper B's filter within 2 x VQF + 0.2°; VQF is taken as the better of its online and
offline forms. The peers' own numbers are pinned to what their packages give with the
same scoring (VQF offline 0.96°, ahrs Madgwick 2.05°, as measured when the issue was
filed), which guards the frame conversions and the scoring.

The peers are the VQF forms and Madgwick 6D (``--peers``): ahrs' Python loops take ~15 s
of CPU for the other three (Madgwick 9D, Mahony 6D/9D), whose frames are checked on a
static sensor in test_attitude_filters.py::test_peers_are_in_the_enu_frame and whose
trial-07 scores are in docs/attitude.md (benchmarks/attitude_bench.py).
"""

from __future__ import annotations

import json

import pytest

from bench.cli import main

TRIAL = "07_undisturbed_fast_rotation_B.hdf5"
FOUR_MINUTES_AT_286_HZ = 240 * 285.714
PEERS_RUN = ("vqf-6d", "vqf-9d", "vqf-offline-6d", "vqf-offline-9d", "madgwick-6d")


@pytest.fixture(scope="module")
def table(tmp_path_factory: pytest.TempPathFactory) -> dict:
    from tests.conftest import SHARED_DATA

    path = SHARED_DATA / "broad" / TRIAL
    pytest.importorskip("h5py")
    pytest.importorskip("vqf")
    pytest.importorskip("ahrs")
    out = tmp_path_factory.mktemp("broad")
    png = out / "errors.png"
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(io.StringIO()):
        assert main(["attitude", str(path), "--compare", "--json", "--png", str(png),
                     "--peers", ",".join(PEERS_RUN)]) == 0
    data = json.loads(buf.getvalue())
    data["png"] = png
    data["rows"] = {r["filter"]: r for r in data["scores"]}
    return data


def _vqf(rows: dict, mode: str, metric: str) -> float:
    return min(rows[f"vqf-{mode}"][metric], rows[f"vqf-offline-{mode}"][metric])


@pytest.mark.slow
def test_default_filter_matches_vqf_on_trial_07(table: dict) -> None:
    rows = table["rows"]
    incl = "inclination_rmse_deg"
    assert rows["default (6D)"][incl] <= 1.25 * _vqf(rows, "6d", incl) + 0.1
    assert rows["default (9D)"][incl] <= 1.25 * _vqf(rows, "6d", incl) + 0.1
    head = "heading_rmse_deg"
    assert rows["default (9D)"][head] <= 1.5 * _vqf(rows, "9d", head) + 0.5


@pytest.mark.slow
def test_paper_b_within_twice_vqf_on_trial_07(table: dict) -> None:
    rows = table["rows"]
    incl = "inclination_rmse_deg"
    assert rows["paper-b (6D)"][incl] <= 2.0 * _vqf(rows, "6d", incl) + 0.2


@pytest.mark.slow
def test_peers_reproduce_their_known_scores(table: dict) -> None:
    rows = table["rows"]
    assert rows["vqf-offline-6d"]["inclination_rmse_deg"] == pytest.approx(0.96, abs=0.02)
    assert rows["madgwick-6d"]["inclination_rmse_deg"] == pytest.approx(2.05, abs=0.05)
    assert rows["vqf-9d"]["heading_rmse_deg"] < 2.0  # 9D: absolute heading, ENU
    assert [r["filter"] for r in table["scores"]] == [
        "default (9D)", "default (6D)", "default-causal (6D)", "paper-b (6D)",
        "paper-b-printed (6D)", *PEERS_RUN]
    assert all(r["samples"] == 33617 for r in table["scores"])
    assert table["png"].stat().st_size > 20_000


@pytest.mark.slow
def test_project_filters_fast_enough_for_four_minutes(table: dict) -> None:
    """CPU time per filter, scaled from trial 07 (52,518 samples) to 4 min at 286 Hz."""
    for r in table["scores"]:
        if r["kind"] == "project":
            assert r["cpu_seconds"] * FOUR_MINUTES_AT_286_HZ / 52518 < 2.0, r["filter"]
