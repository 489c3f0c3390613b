"""BROAD scoring against hand-computed cases: identity, known rotations, the movement mask."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis import quaternion as quat
from analysis.attitude_scoring import error_angles, error_quaternion_earth, score

Z = [0.0, 0.0, 1.0]
X = [1.0, 0.0, 0.0]


def _rot(axis, deg: float) -> np.ndarray:
    return quat.from_axis_angle(axis, math.radians(deg))


def _refs(n: int = 50) -> np.ndarray:
    rng = np.random.default_rng(1)
    return quat.normalize(rng.normal(size=(n, 4)))


def test_identity_scores_zero() -> None:
    q = _refs()
    s = score(q, q)
    assert s.total_rad == pytest.approx(0, abs=1e-7) and s.samples == 50
    assert s.heading_rad == pytest.approx(0, abs=1e-7)
    assert s.inclination_rad == pytest.approx(0, abs=1e-7)
    assert score(-q, q).total_rad == pytest.approx(0, abs=1e-7)  # q and -q: same attitude


def test_heading_error_is_a_turn_about_the_earth_vertical() -> None:
    ref = _refs()
    est = quat.multiply(_rot(Z, 10.0), ref)  # earth frame: rotate the estimate about up
    d = score(est, ref).as_deg()
    assert d["heading_rmse_deg"] == pytest.approx(10.0)
    assert d["inclination_rmse_deg"] == pytest.approx(0.0, abs=1e-5)
    assert d["total_rmse_deg"] == pytest.approx(10.0)


def test_inclination_error_is_a_tilt_of_the_earth_frame() -> None:
    ref = _refs()
    est = quat.multiply(_rot([1.0, 1.0, 0.0], 4.0), ref)  # any horizontal axis
    d = score(est, ref).as_deg()
    assert d["inclination_rmse_deg"] == pytest.approx(4.0)
    assert d["heading_rmse_deg"] == pytest.approx(0.0, abs=1e-5)


def test_error_is_taken_in_the_earth_frame_not_the_body_frame() -> None:
    """Pitched 90°, an error about the body z axis tilts the earth frame: inclination."""
    ref = _rot([0.0, 1.0, 0.0], 90.0)
    est = quat.multiply(ref, _rot(Z, 10.0))  # body-frame yaw error
    total, heading, incl = (math.degrees(float(v)) for v in
                            error_angles(error_quaternion_earth(est, ref)))
    assert incl == pytest.approx(10.0) and heading == pytest.approx(0.0, abs=1e-6)
    assert total == pytest.approx(10.0)


def test_combined_heading_and_tilt_hand_computed() -> None:
    """q_err = Rz(30°)⊗Rx(40°): w = cos15·cos20, z = sin15·cos20.

    heading = 2·atan(tan 15°) = 30°, inclination = 2·acos(cos 20°) = 40°, total =
    2·acos(cos15·cos20) = 49.0°.
    """
    ref = _refs(5)
    est = quat.multiply(quat.multiply(_rot(Z, 30.0), _rot(X, 40.0)), ref)
    d = score(est, ref).as_deg()
    assert d["heading_rmse_deg"] == pytest.approx(30.0)
    assert d["inclination_rmse_deg"] == pytest.approx(40.0)
    total = 2 * math.degrees(math.acos(math.cos(math.radians(15)) * math.cos(math.radians(20))))
    assert d["total_rmse_deg"] == pytest.approx(total)


def test_movement_mask_and_missing_reference() -> None:
    ref = _refs(4)
    errs = [2.0, 4.0, 100.0, 6.0]
    est = np.stack([quat.multiply(_rot(X, e), r) for e, r in zip(errs, ref, strict=True)])
    ref_nan = ref.copy()
    ref_nan[3] = np.nan  # marker loss: skipped
    s = score(est, ref_nan, movement=[True, True, False, True])  # sample 2 not scored
    assert s.samples == 2
    assert math.degrees(s.inclination_rad) == pytest.approx(math.sqrt((4 + 16) / 2))
    with pytest.raises(ValueError, match="no samples"):
        score(est, ref, movement=[False] * 4)
    with pytest.raises(ValueError, match="movement mask"):
        score(est, ref, movement=[True] * 3)


def test_6d_heading_offset_is_removed_only_on_request() -> None:
    ref = _refs()
    est = quat.multiply(_rot(Z, -70.0), quat.multiply(_rot(X, 3.0), ref))
    plain = score(est, ref).as_deg()
    six = score(est, ref, remove_heading_offset=True).as_deg()
    assert plain["heading_rmse_deg"] > 60
    assert six["heading_offset_removed_deg"] == pytest.approx(-70.0, abs=0.5)
    assert six["heading_rmse_deg"] < 0.5
    assert six["inclination_rmse_deg"] == pytest.approx(plain["inclination_rmse_deg"])
