"""A calibration whose motions exceed what the controller itself reports (TMN?/TMX?), or
a hexapod that is not referenced, is refused before anything moves (sim-imu-tcp.toml:
the real PI GCS backend against the simulated controller over loopback TCP)."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.jobs.calibration_stages import run_calibration
from bench.rig.rig import load_imu_rig
from drivers.errors import DeviceError
from drivers.factory import open_rig

REPO = Path(__file__).resolve().parents[3]
RIG = load_imu_rig(REPO / "bench" / "data" / "rigs" / "sim-imu-tcp.toml")


def _opened(change):
    """open_bench for run_calibration: the simulated controller changed after open."""
    benches = []

    def open_bench(rig, seed=None):
        bench = open_rig(rig, seed=seed)
        change(bench.wire)
        benches.append(bench)
        return bench

    return open_bench, benches


def _moved(wire) -> list[str]:
    """Commands that move or set up motion (``WGO n 0``, the stop at close, does not)."""
    return [c.name for c in wire.commands if c.name in ("MOV", "MVR", "SPI", "WAV")
            or (c.name == "WGO" and "1" in c.args[1::2])]


def test_motions_beyond_the_controllers_travel_are_refused_before_any_motion(tmp_path):
    def narrow(wire):
        wire.travel["U"] = (-1.0, 1.0)  # the controller allows only +-1 deg of roll

    open_bench, benches = _opened(narrow)
    with pytest.raises(DeviceError, match=r"reaches U = .* rad, beyond the controller's TM[NX]"
                                          r"\? U = -?0.0174533 rad; refused before it starts"):
        run_calibration(RIG, tmp_path, quick=True, open_bench=open_bench)
    (bench,) = benches
    assert _moved(bench.wire) == []  # no move, no wave generator started, no pivot set
    assert not list(tmp_path.glob("*/run.json"))  # no run was started


def test_an_unreferenced_hexapod_is_refused_before_any_motion(tmp_path):
    def unreferenced(wire):
        wire.referenced = False

    open_bench, benches = _opened(unreferenced)
    with pytest.raises(DeviceError, match=r"not referenced \(FRF\? X=0\): reference it"):
        run_calibration(RIG, tmp_path, quick=True, open_bench=open_bench)
    assert _moved(benches[0].wire) == []
