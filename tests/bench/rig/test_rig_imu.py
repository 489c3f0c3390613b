"""IMU-bench rig files: validation errors name the file and the field."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.errors import RigError
from bench.rig.rig import default_imu_rig_path, default_rig_path, is_imu_rig, load_imu_rig

TEXT = default_imu_rig_path().read_text(encoding="utf-8")


def _rig(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "imu.toml"
    p.write_text(text, encoding="utf-8")
    return p


def test_shipped_rig_loads_with_the_paper_a_imu() -> None:
    rig = load_imu_rig(default_imu_rig_path())
    assert rig.is_simulated and rig.name == "sim-imu"
    assert rig.sim.imu["lever_arm_m"] == (0.365, -0.235, 0.230)
    assert rig.sim.imu["mounting_deg"] == (0.0, 0.0, 17.0)
    assert rig.imu.measured_mounting_deg == (0.0, 0.0, 17.0)
    assert rig.hexapod.hexapod_limits().rate_rad_s == 0.7
    assert is_imu_rig(default_imu_rig_path()) and not is_imu_rig(default_rig_path())


@pytest.mark.parametrize(("old", "new", "field"), [
    ('kind = "imu"', 'kind = "thrust"', "[rig] kind"),
    ('[devices.imu]\nurl = "sim://imu"', '[devices.imu]\nurl = "sim://hexapod"',
     "[devices.imu] url"),
    ('[devices.imu]\nurl = "sim://imu"', "", "[devices] imu"),
    ("log_rate_hz = 1000.0", "log_rate_hz = 0.0", "[hexapod] log_rate_hz"),
    ("velocity_m_s = 0.6", "velocity_m_s = 0.6\nthrust_n = 3", "[hexapod] thrust_n"),
    ("rate_hz = 100.0\ngyro", "rate_hz = -100.0\ngyro", "[imu] rate_hz"),
    ("clock_offset_s = 0.0237", "clock_offset = 0.0237", "[sim.imu] clock_offset"),
    ("seed = 0", "seed = 1.5", "[sim] seed"),
])
def test_bad_fields_are_named(tmp_path: Path, old: str, new: str, field: str) -> None:
    assert old in TEXT
    with pytest.raises(RigError) as err:
        load_imu_rig(_rig(tmp_path, TEXT.replace(old, new, 1)))
    assert "imu.toml" in str(err.value) and field in str(err.value)
    assert err.value.exit_code == 2


def test_missing_file_and_bad_toml(tmp_path: Path) -> None:
    with pytest.raises(RigError, match="not found"):
        load_imu_rig(tmp_path / "nope.toml")
    with pytest.raises(RigError, match="not valid TOML"):
        load_imu_rig(_rig(tmp_path, "[rig\n"))
