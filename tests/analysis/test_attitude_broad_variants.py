"""The default filter and Paper B's against VQF on the BROAD family's shapes, from trial 07.

The issue's held-back check runs the default filter on other BROAD trials (slow rotation,
translation, breaks, tapping, vibration, magnets); only trial 07 ships. Each variant here
gives trial 07's real samples one of those shapes (``drivers.sim.imu_disturbances``) and
checks the issue's bounds against online VQF (the ``vqf`` package's ``VQF``, defaults) on
the same samples: inclination RMSE <= 1.25 x VQF 6D + 0.1° on every variant, heading
RMSE <= 1.5 x VQF 9D + 0.5° on the undisturbed ones. The default is VQF's offline form, so
the second set of tests checks that what the default relies on is really switched on and
really helps: turned off in the same ``offlineVQF``, each one makes its case worse. The
third set holds ``paper-b`` to its bound, inclination RMSE <= 2 x VQF 6D + 0.5° (VQF
the better of online and offline) on every variant, including fast rotation at a lever arm
with translation, where Paper B's printed correction tilts by 10-20°.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from scipy.signal import savgol_filter
from scipy.spatial.transform import Rotation

from analysis.attitude_filters import run_filter
from analysis.attitude_scoring import score
from analysis.imu_recording import ImuRecording, read_broad
from drivers.sim.imu_disturbances import UNDISTURBED, VARIANTS, fill_gaps, make_variant

TRIAL = "07_undisturbed_fast_rotation_B.hdf5"
vqf = pytest.importorskip("vqf")
pytestmark = pytest.mark.slow  # ~35 s in all: trial 07 and eleven variants through the filters


@pytest.fixture(scope="module")
def trial() -> dict:
    from tests.conftest import SHARED_DATA

    path = SHARED_DATA / "broad" / TRIAL
    pytest.importorskip("h5py")
    r = read_broad(path)
    return {"t_s": r.t_s, "gyro": r.gyro_rad_s, "acc": r.acc_m_s2, "mag": r.mag_ut,
            "quat": r.ref_quat, "movement": r.movement}


def _rec(d: dict) -> ImuRecording:
    return ImuRecording("variant", d["t_s"], d["gyro"], d["acc"], d["mag"], d["quat"],
                        d["movement"])


class _Cases:
    """Trial 07, each variant (seed 0), each filter's attitude on it and its scores, computed
    once for the module: the tests below score the same VQF runs on the same variants
    several times, and run offlineVQF's defaults on one variant three times."""

    def __init__(self, trial: dict) -> None:
        self.trial = trial
        self._kept: dict[tuple, Any] = {}

    def _once(self, key: tuple, make: Callable[[], Any]) -> Any:
        """``make()``, the first time ``key`` is asked for; what it gave, after that."""
        if key not in self._kept:
            self._kept[key] = make()
        return self._kept[key]

    def data(self, name: str) -> dict:
        if name in ("trial 07", "base"):
            return self.trial
        return self._once(("data", name), lambda: make_variant(self.trial, name, seed=0))

    def run(self, name: str, filt: str, **options: object) -> tuple[np.ndarray, bool]:
        """The filter's quaternions on the case, and whether it used the magnetometer."""
        def make() -> tuple[np.ndarray, bool]:
            out = run_filter(filt, _rec(self.data(name)), **options)
            return out.quat, out.nine_d

        return self._once(("run", name, filt, *sorted(options.items())), make)

    def offline(self, name: str, **params: object) -> dict:
        """``offlineVQF`` on the case with ``params`` (the package's defaults if none)."""
        return self._once(("offline", name, *sorted(params.items())),
                          lambda: _offline(self.data(name), **params))

    def deg(self, name: str, filt: str, nine_d: bool) -> tuple[float, float]:
        """``_deg`` of the filter's run on the case (9D or 6D scoring)."""
        return self._once(("deg", name, filt, nine_d),
                          lambda: _deg(self.run(name, filt)[0], self.data(name), nine_d))


@pytest.fixture(scope="module")
def cases(trial: dict) -> _Cases:
    return _Cases(trial)


def _deg(q: np.ndarray, d: dict, nine_d: bool) -> tuple[float, float]:
    """Inclination and heading RMSE (deg), BROAD scoring; 6D heading after its offset."""
    s = score(q, d["quat"], d["movement"], remove_heading_offset=not nine_d)
    return math.degrees(s.inclination_rad), math.degrees(s.heading_rad)


@pytest.mark.parametrize("name", list(VARIANTS))
def test_default_within_the_issue_bounds_of_vqf(cases: _Cases, name: str) -> None:
    d = cases.data(name)
    default, nine_d = cases.run(name, "default")
    assert nine_d  # a BROAD trial has a magnetometer: the default is 9D
    incl, head = _deg(default, d, True)
    vqf6_incl, _ = cases.deg(name, "vqf-6d", False)
    _, vqf9_head = cases.deg(name, "vqf-9d", True)
    assert incl <= 1.25 * vqf6_incl + 0.1, (incl, vqf6_incl)
    if name in UNDISTURBED:
        assert head <= 1.5 * vqf9_head + 0.5, (head, vqf9_head)


def _offline(d: dict, **params: object) -> dict:
    c = np.ascontiguousarray
    return vqf.offlineVQF(c(d["gyro"]), c(d["acc"]), c(d["mag"]),
                          float(np.median(np.diff(d["t_s"]))), params or None)


@pytest.mark.parametrize(("name", "off", "quat", "metric", "worse_by"), [
    # gyro bias (rest and motion): 6D heading drifts without it (measured 1.1° -> 6.5°,
    # slowed 1.4° -> 18°)
    ("base", {"restBiasEstEnabled": False, "motionBiasEstEnabled": False}, "quat6D",
     "heading", 3.0),
    ("slow_rotation", {"restBiasEstEnabled": False, "motionBiasEstEnabled": False},
     "quat6D", "heading", 5.0),
    # rest detection: with only the motion estimate the bias is found worse (1.4° -> 5.3°)
    ("slow_rotation", {"restBiasEstEnabled": False}, "quat6D", "heading", 2.0),
    # magnetic disturbance rejection (measured 1.2° -> 7.9° with a magnet passing by)
    ("stationary_magnet", {"magDistRejectionEnabled": False}, "quat9D", "heading", 3.0),
    # accelerometer disturbances are rejected by the 3 s inertial low-pass; a 0.3 s one
    # lets them through (translation 0.96° -> 8.7°, tapping 1.0° -> 1.75°)
    ("translation", {"tauAcc": 0.3}, "quat6D", "inclination", 3.0),
    ("tapping", {"tauAcc": 0.3}, "quat6D", "inclination", 1.4),
])
def test_default_chain_is_active_and_helps(cases: _Cases, name: str, off: dict, quat: str,
                                           metric: str, worse_by: float) -> None:
    d = cases.data(name)
    nine_d = quat == "quat9D"
    default, _ = cases.run(name, "default", six_d=not nine_d)
    with_it = _deg(default, d, nine_d)
    # the default is offlineVQF with the package's defaults: identical to calling it
    np.testing.assert_allclose(default, cases.offline(name)[quat], atol=1e-9)
    without = _deg(cases.offline(name, **off)[quat], d, nine_d)
    i = 0 if metric == "inclination" else 1
    assert without[i] > worse_by * with_it[i], (with_it, without)


def test_variants_have_the_shapes_they_claim(trial: dict) -> None:
    """Each variant changes what it says and keeps the rest (a guard on the generator)."""
    acc0 = trial["acc"]
    mov = trial["movement"]
    tap = make_variant(trial, "tapping")
    spikes = np.linalg.norm(tap["acc"] - acc0, axis=1)
    assert spikes.max() > 15.0 and np.mean(spikes > 1.0) < 0.1  # short, strong spikes
    assert np.all(tap["acc"][~mov][:1000] == acc0[~mov][:1000])  # only during movement
    tr = make_variant(trial, "translation")
    lin = np.linalg.norm(tr["acc"] - acc0, axis=1)[mov]
    assert np.sqrt(np.mean(lin**2)) > 1.5  # sustained, m/s² RMS
    np.testing.assert_array_equal(tr["gyro"], trial["gyro"])
    mag = make_variant(trial, "stationary_magnet")
    extra = np.linalg.norm(mag["mag"] - trial["mag"], axis=1)
    assert 20.0 < extra.max() < 60.0 and np.mean(extra > 5.0) > 0.1  # tens of µT, seconds
    br = make_variant(trial, "with_breaks")
    rate = 1.0 / np.median(np.diff(trial["t_s"]))
    assert len(br["t_s"]) == len(trial["t_s"]) + 3 * round(10.0 * rate)
    still = np.all(np.diff(br["quat"], axis=0) == 0.0, axis=1) & br["movement"][1:]
    assert still.sum() >= 3 * (round(10.0 * rate) - 1)  # three 10 s rests, scored
    slow = make_variant(trial, "slow_rotation")
    assert len(slow["t_s"]) == pytest.approx(3 * len(trial["t_s"]), abs=3)
    peak = np.percentile(np.abs(trial["gyro"][mov]), 99)
    assert np.percentile(np.abs(slow["gyro"][slow["movement"]]), 99) < 0.4 * peak
    # white noise kept at its measured level in the rest (interpolation would lower it)
    rest = slice(round(5 * rate), round(15 * rate))
    assert slow["gyro"][rest].std(axis=0) == pytest.approx(trial["gyro"][rest].std(axis=0),
                                                           rel=0.15)


@pytest.mark.parametrize("name", ["paper-b", "paper-b-printed"])
def test_paper_b_is_not_tilted_by_vibration(cases: _Cases, name: str) -> None:
    """A zero-mean vibration rectified by the normalisation of the accelerometer tilted
    Paper B's printed correction (measured 1.63° -> 2.20° on the vibration variant); the
    (B.28) low-pass ahead of it (τ_a = 5 ms) removes that (1.64° -> 1.66°). ``paper-b``
    low-passes in the earth frame before normalising, linearly: 1.03° -> 1.03°."""
    still = cases.deg("trial 07", name, False)[0]
    shaken = cases.deg("vibration", name, False)[0]
    assert shaken < 1.1 * still


LIVELY = ("swing_wrist", "swing_forearm", "combined_with_breaks")


def _vqf_6d_incl(cases: _Cases, name: str) -> float:
    """VQF's 6D inclination RMSE, the better of its online and offline forms."""
    return min(cases.deg(name, n, False)[0] for n in ("vqf-6d", "vqf-offline-6d"))


@pytest.mark.parametrize("name", ["trial 07", *VARIANTS])
def test_paper_b_within_twice_vqf_plus_half_a_degree(cases: _Cases, name: str) -> None:
    """``paper-b`` within 2 x VQF 6D + 0.5° on every BROAD-shaped variant. Before the
    earth-frame low-pass (``paper-b-printed`` now) the lively ones failed it: measured
    7.6-22° (swing at the wrist 14.6°, at the forearm 20.6°, combined with breaks 11.4°)
    against VQF's 1.0-1.7°."""
    incl = cases.deg(name, "paper-b", False)[0]
    vqf6 = _vqf_6d_incl(cases, name)
    assert incl <= 2.0 * vqf6 + 0.5, (incl, vqf6)


@pytest.mark.parametrize("name", LIVELY)
def test_lively_variants_tilt_the_printed_correction(cases: _Cases, name: str) -> None:
    """The reproduction: on fast rotation combined with translation, Paper B's printed
    correction (each sample's normalised accelerometer) is far outside the bound."""
    printed = cases.deg(name, "paper-b-printed", False)[0]
    assert printed > 3.0 * (2.0 * _vqf_6d_incl(cases, name) + 0.5), printed


def test_swing_is_a_bounded_translation_with_a_sustained_centripetal_part(trial: dict) -> None:
    """The swing variants add what a sensor turned about a pivot 10-20 cm away feels: large
    (tens of m/s² RMS), zero mean in the earth frame (the position stays on a sphere), yet
    its centripetal part alone, always towards the pivot, averages to several m/s²."""
    mov = trial["movement"]
    rot = Rotation.from_quat(fill_gaps(trial["quat"])[:, [1, 2, 3, 0]])
    w = savgol_filter(trial["gyro"], 15, 2, axis=0)
    for name, lever in (("swing_wrist", (0.0, 0.1, 0.0)),
                        ("swing_forearm", (0.12, 0.12, -0.1))):
        d = make_variant(trial, name)
        np.testing.assert_array_equal(d["gyro"], trial["gyro"])
        extra = rot.apply(d["acc"] - trial["acc"])[mov]
        rms = np.sqrt(np.mean(np.sum(extra**2, axis=1)))
        assert rms > 10.0 and np.linalg.norm(extra.mean(axis=0)) < 0.02 * rms
        centripetal = rot.apply(np.cross(w, np.cross(w, lever)))[mov]
        assert np.linalg.norm(centripetal.mean(axis=0)) > 3.0
    rate = 1.0 / np.median(np.diff(trial["t_s"]))
    combined = make_variant(trial, "combined_with_breaks")
    assert len(combined["t_s"]) == len(trial["t_s"]) + 3 * round(10.0 * rate)
