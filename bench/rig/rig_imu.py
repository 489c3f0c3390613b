"""The IMU bench's own sections of a rig file: a hexapod, the IMU under test and a
reference IMU (Paper A/B).

``[rig] kind = "imu"`` marks the file. :func:`parse` reads its tables into the fields of
the one :class:`bench.rig.rig.RigConfig`; problems raise ``RigError`` naming the file and the
field.

Layout (see ``bench/data/rigs/sim-imu.toml``): ``[devices.hexapod|imu|reference_imu]`` with
``url`` (and ``options``), ``[hexapod]`` limits, pivot and log/trajectory rates, ``[imu]``
the datasheet figures of the IMU under test and the operator's measured mounting,
``[reference_imu]`` the simulated reference's rate and noise, ``[sim]`` seed, noise switch,
the true centre of gravity and ``[sim.imu]`` the hidden errors of the simulated IMU.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.rig.rig_devices import DeviceConfig, parse_device
from bench.rig.rig_table import RigTable
from drivers.contracts import HexapodLimits
from drivers.sim.imu import ImuModel

__all__ = ["HEXAPOD_LIMIT_MAXIMA", "ROLES", "HexapodSettings", "ImuSettings", "ImuSimConfig",
           "parse"]

ROLES = ("hexapod", "imu", "reference_imu")
REQUIRED_ROLES = ("hexapod", "imu")
_VECTOR_FIELDS = {f.name for f in dataclasses.fields(ImuModel)
                  if isinstance(getattr(ImuModel(), f.name), tuple)}
# Datasheet figures (real and simulated rigs) vs the hidden errors only a simulator has.
IMU_DATASHEET = ("rate_hz", "gyro_range_rad_s", "acc_range_m_s2", "gyro_noise_density",
                 "acc_noise_density", "gyro_lsb_rad_s", "acc_lsb_m_s2")
IMU_SIM_ERRORS = tuple(f.name for f in dataclasses.fields(ImuModel)
                       if f.name not in IMU_DATASHEET)
REFERENCE_KEYS = ("rate_hz", "attitude_noise_rad", "gyro_noise_rad_s")
#: The largest hexapod limit a rig file may set (SI), well beyond motion-simulator
#: hexapods (Paper A's: 0.6 m/s, 6 m/s^2, 0.7 rad/s, 0.25 m, 25 deg); above it the
#: limit would no longer stop anything.
HEXAPOD_LIMIT_MAXIMA = {"velocity_m_s": 10.0, "acceleration_m_s2": 100.0, "rate_rad_s": 20.0,
                        "angular_acceleration_rad_s2": 500.0, "position_m": 2.0,
                        "angle_rad": math.pi}


@dataclass(frozen=True)
class HexapodSettings:
    """Limits (``HexapodLimits`` fields), pivot (the UAV's centre of gravity, m), rates."""

    limits: Mapping[str, float]
    pivot_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    log_rate_hz: float = 1000.0
    trajectory_rate_hz: float = 200.0

    def hexapod_limits(self) -> HexapodLimits:
        return HexapodLimits(**dict(self.limits))


@dataclass(frozen=True)
class ImuSettings:
    """Datasheet figures of the IMU under test and the measured mounting (A.15), degrees."""

    model: str = "ADIS16400"
    params: Mapping[str, Any] = field(default_factory=dict)
    measured_mounting_deg: tuple[float, float, float] | None = None

    def value(self, name: str) -> float:
        return float(self.params.get(name, getattr(ImuModel(), name)))


@dataclass(frozen=True)
class ImuSimConfig:
    seed: int = 0
    noise: bool = True
    cg_m: tuple[float, float, float] | None = None  # true CG; None: at the pivot
    imu: Mapping[str, Any] = field(default_factory=dict)  # hidden ImuModel errors


def _vector(t: RigTable, key: str, default: tuple[float, ...] | None = None
            ) -> tuple[float, float, float] | None:
    if key not in t.data:
        return default  # type: ignore[return-value]
    v = t.data[key]
    ok = isinstance(v, list) and len(v) == 3 and all(
        isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in v)
    if not ok:
        t.fail(key, f"expected three finite numbers, got {v!r}")
    return tuple(float(x) for x in v)  # type: ignore[return-value]


def _model_fields(t: RigTable, names: tuple[str, ...]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name in names:
        if name not in t.data:
            continue
        if name in _VECTOR_FIELDS:
            out[name] = _vector(t, name)
        else:
            lo = 0.0 if name != "clock_offset_s" else -10.0
            out[name] = t.number(name, lo=lo, hi=1e9)
            if name in ("rate_hz", "gyro_range_rad_s", "acc_range_m_s2") and out[name] <= 0:
                t.fail(name, f"expected a positive number, got {out[name]}")
    return out


def _device(top: RigTable, role: str) -> DeviceConfig:
    want = role.replace("_", "-")

    def sim_problem(url: str) -> str | None:
        if url != f"sim://{want}":
            return f"{url!r}: a simulated {role} must be sim://{want}"
        return None

    return parse_device(top, role, keys=("options",),
                        scheme_of=lambda url: url.split("://", 1)[0] if "://" in url else "",
                        sim_problem=sim_problem)


def parse(path: Path, top: RigTable) -> dict[str, Any]:
    """An IMU-bench rig file's tables as the fields of :class:`bench.rig.rig.RigConfig`."""
    top.only("rig", "devices", "hexapod", "imu", "reference_imu", "sim")
    rig = top.table("rig")
    assert rig is not None
    rig.only("name", "kind", "description")
    if rig.text("kind", "") != "imu":
        rig.fail("kind", "expected \"imu\" for an IMU-bench rig (hexapod + IMU)")
    devs = top.table("devices")
    assert devs is not None
    devs.only(*ROLES)
    for role in REQUIRED_ROLES:
        if role not in devs.data:
            devs.fail(role, f"missing device; an IMU bench needs {', '.join(REQUIRED_ROLES)}")
    devices = {role: _device(devs, role) for role in ROLES if role in devs.data}

    hx = top.table("hexapod", required=False) or RigTable(path, "hexapod", {})
    hx.only(*HexapodLimits.names(), "pivot_m", "log_rate_hz", "trajectory_rate_hz")
    limits = {n: hx.number(n, getattr(HexapodLimits(), n), lo=0.0, hi=HEXAPOD_LIMIT_MAXIMA[n])
              for n in HexapodLimits.names()}
    for n, v in limits.items():
        if not v > 0:  # type: ignore[operator]
            hx.fail(n, f"expected a positive limit, got {v}")
    hexapod = HexapodSettings(
        limits=limits,  # type: ignore[arg-type]
        pivot_m=_vector(hx, "pivot_m", (0.0, 0.0, 0.0)),  # type: ignore[arg-type]
        log_rate_hz=hx.number("log_rate_hz", 1000.0, lo=1.0, hi=1e5, unit="Hz"),
        trajectory_rate_hz=hx.number("trajectory_rate_hz", 200.0, lo=1.0, hi=1e5,
                                     unit="Hz"),
    )

    it = top.table("imu", required=False) or RigTable(path, "imu", {})
    it.only("model", *IMU_DATASHEET, "measured_mounting_deg")
    imu = ImuSettings(it.text("model", "ADIS16400"), _model_fields(it, IMU_DATASHEET),
                      _vector(it, "measured_mounting_deg"))

    rt = top.table("reference_imu", required=False) or RigTable(path, "reference_imu", {})
    rt.only(*REFERENCE_KEYS)
    reference = {k: rt.number(k, lo=0.0, hi=1e6) for k in REFERENCE_KEYS if k in rt.data}
    rate_hz = reference.get("rate_hz", 1.0)
    if rate_hz is not None and rate_hz <= 0:
        rt.fail("rate_hz", "expected a positive rate")

    st = top.table("sim", required=False) or RigTable(path, "sim", {})
    st.only("seed", "noise", "cg_m", "imu")
    seed = st.number("seed", 0.0, lo=0.0, hi=2**63)
    if seed != int(seed):
        st.fail("seed", f"expected a whole number, got {seed}")
    sim_imu = st.table("imu", required=False) or RigTable(path, "sim.imu", {})
    sim_imu.only(*IMU_SIM_ERRORS)
    sim = ImuSimConfig(int(seed), st.flag("noise", True), _vector(st, "cg_m"),  # type: ignore[arg-type]
                       _model_fields(sim_imu, IMU_SIM_ERRORS))
    return {"path": path, "name": rig.text("name"), "devices": devices, "hexapod": hexapod,
            "imu": imu, "reference_imu": reference, "sim": sim,
            "description": rig.text("description", "")}
