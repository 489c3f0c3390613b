"""The rig the drivers read: bench's RigConfig fits ``drivers.rig_view.RigView``.

The type checker reads this file too (``[tool.basedpyright] include``): ``_as_view`` is
where a RigConfig that stopped fitting the protocol fails the check.
"""

from __future__ import annotations

import pytest

from bench.rig.rig import RigConfig, default_imu_rig_path, default_rig_path, load_any_rig
from drivers.errors import DeviceError
from drivers.rig_view import (
    DeviceView,
    EscView,
    HexapodView,
    ImuSimView,
    ImuView,
    PropulsionSimView,
    RigView,
    imu_sim,
    propulsion_sim,
    section,
)


def _as_view(rig: RigConfig) -> RigView:
    return rig


def _members(protocol: type) -> set[str]:
    return {n for n in vars(protocol) if not n.startswith("_")}


def _assert_fits(obj: object, protocol: type) -> None:
    missing = sorted(n for n in _members(protocol) if not hasattr(obj, n))
    assert not missing, f"{type(obj).__name__} lacks {missing} of {protocol.__name__}"


def test_a_propulsion_rig_has_what_the_drivers_read() -> None:
    rig = _as_view(load_any_rig(default_rig_path()))
    _assert_fits(rig, RigView)
    for dev in rig.devices.values():
        _assert_fits(dev, DeviceView)
    _assert_fits(section(rig, rig.esc, "esc"), EscView)
    sim = propulsion_sim(rig)
    _assert_fits(sim, PropulsionSimView)
    assert sim is rig.sim
    with pytest.raises(DeviceError, match=r"\[sim\] is not an IMU bench's"):
        imu_sim(rig)
    with pytest.raises(DeviceError, match=r"sim\.toml: no \[hexapod\] table"):
        section(rig, rig.hexapod, "hexapod")


def test_an_imu_rig_has_what_the_drivers_read() -> None:
    rig = _as_view(load_any_rig(default_imu_rig_path()))
    _assert_fits(rig, RigView)
    _assert_fits(section(rig, rig.hexapod, "hexapod"), HexapodView)
    _assert_fits(section(rig, rig.imu, "imu"), ImuView)
    assert section(rig, rig.reference_imu, "reference_imu") is rig.reference_imu
    sim = imu_sim(rig)
    _assert_fits(sim, ImuSimView)
    with pytest.raises(DeviceError, match=r"\[sim\] is not a propulsion stand's"):
        propulsion_sim(rig)
    with pytest.raises(DeviceError, match=r"no \[esc\] table"):
        section(rig, rig.esc, "esc")
