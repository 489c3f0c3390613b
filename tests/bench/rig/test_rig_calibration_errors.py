"""A device calibration or option the simulated devices cannot use is refused when the rig
loads: one line naming the rig file, the device table and the key, exit 2, and no run
folder (it used to surface when the device opened, naming only the sim:// URL, after a
run folder with status 'fail' had been written)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from bench.cli import main
from bench.errors import RigError
from bench.rig.rig import load_rig
from drivers.errors import DeviceError
from drivers.sim.rig import SimRig


def _edit(rig: Path, old: str, new: str) -> Path:
    text = rig.read_text(encoding="utf-8")
    assert old in text
    rig.write_text(text.replace(old, new, 1), encoding="utf-8")
    return rig


@pytest.mark.parametrize(("old", "new", "table", "key", "expected"), [
    ("magnets = 14", "magnets = 0", "rpm", "magnets",
     "expected a whole number of magnets >= 1, got 0"),
    ("magnets = 14", "magnets = 2.5", "rpm", "magnets",
     "expected a whole number of magnets >= 1, got 2.5"),
    ("scale_n_per_v = 10.0", "scale_n_per_v = 0.0", "load_cell", "scale_n_per_v",
     "expected a number of N/V > 0, got 0"),
    ("current_mv_per_a = 36.60", "current_mv_per_a = -36.60", "power", "current_mv_per_a",
     "expected a number of mV/A > 0, got -36.6"),
    ("magnets = 14", "magnets = 14, magnet = 7", "rpm", "magnet",
     "unknown key; expected one of magnets"),
])
def test_step_refuses_a_bad_calibration_before_any_run_folder(
        sim_rig_mapped_path, tmp_path, capsys, old, new, table, key, expected):
    rig = _edit(sim_rig_mapped_path, old, new)
    out = tmp_path / "runs"
    code = main(["step", "--rig", str(rig), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.strip().splitlines() == [
        f"rotorbench: error: {rig}: [devices.{table}] calibration.{key}: {expected}"]
    assert not out.exists() or not any(out.iterdir())  # nothing recorded, not even 'fail'


def test_a_bad_fault_option_names_the_table_at_load(sim_rig_mapped_path):
    rig = _edit(sim_rig_mapped_path, "calibration = { magnets = 14 }",
                'calibration = { magnets = 14 }\noptions = { faults = [{ kind = "melted" }] }')
    with pytest.raises(RigError, match=re.escape(f"{rig}: [devices.rpm] options.faults: "
                                                 "bad fault spec")):
        load_rig(rig)
    _edit(rig, '"melted"', '"timeout", at_s = 1.0')
    assert load_rig(rig).devices["rpm"].options["faults"][0]["kind"] == "timeout"


def test_the_sim_rig_itself_refuses_a_zero_current_scale():
    # built directly (no rig file): the URL names the device; was a ZeroDivisionError
    with pytest.raises(DeviceError, match=r"sim://power: calibration.current_mv_per_a: "
                                          r"expected a number of mV/A > 0, got 0"):
        SimRig(power_cal={"current_mv_per_a": 0.0})
