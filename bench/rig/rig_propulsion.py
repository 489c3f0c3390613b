"""The propulsion stand's own sections of a rig file: limits, components, ESC, simulator
and static thrust map (Paper C section 4.4).

:func:`parse` reads a propulsion rig file's tables (``[rig]``, ``[devices.esc|load_cell|
power|rpm]``, ``[limits]``, ``[components]``, ``[esc]``, ``[sim]``, ``[thrust_map]``)
into the fields of the one :class:`bench.rig.rig.RigConfig`; any problem raises ``RigError``
naming the file, the field and what was expected.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import numpy as np

from bench.errors import RigError, ThrustOutsideMap
from bench.paths.inputs import check_input
from bench.rig.rig_devices import DeviceConfig, parse_device
from bench.rig.rig_table import RigTable
from optimizer.catalogs.shipped_data import CATALOGS

__all__ = ["ESC_MODES", "LIMIT_MAXIMA", "ROLES", "Components", "EscConfig", "Limits",
           "SimConfig", "ThrustMap", "make_thrust_map", "parse", "read_thrust_map"]

ROLES = ("esc", "load_cell", "power", "rpm")
ESC_MODES = ("complementary", "diode", "stock")
FRAME_RATE_RANGE_HZ = (50.0, 490.0)
PULSE_RANGE_US = (1000.0, 2000.0)


_MAXIMA = ("thrust_n", "current_a", "rpm", "voltage_max_v", "temperature_c")
_MINIMA = ("voltage_min_v",)


@dataclass(frozen=True)
class Limits:
    """Safety limits; a sequence may only tighten them (``tightened``). None = no limit."""

    thrust_n: float | None = None
    current_a: float | None = None
    rpm: float | None = None
    voltage_min_v: float | None = None
    voltage_max_v: float | None = None
    temperature_c: float | None = None
    source: str = field(default="", compare=False)

    def tightened(self, other: Limits) -> Limits:
        """Limits with ``other``'s values where set; raises ``RigError`` if any is looser."""
        where = f"{self.source}: " if self.source else ""
        out: dict[str, float | None] = {}
        for name in _MAXIMA + _MINIMA:
            mine, theirs = getattr(self, name), getattr(other, name)
            if theirs is None:
                out[name] = mine
                continue
            looser = (
                mine is not None
                and (theirs > mine if name in _MAXIMA else theirs < mine)
            )
            if looser or not math.isfinite(theirs):
                raise RigError(
                    f"{where}[limits] {name}: a sequence may only tighten limits "
                    f"(rig {mine}, requested {theirs})"
                )
            out[name] = theirs
        return replace(self, **out)

    def as_dict(self) -> dict[str, float | None]:
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name != "source"}


@dataclass(frozen=True)
class Components:
    """The hardware under test, as ids of a shipped optimizer catalog
    (``optimizer/data/catalogs/<id>``)."""

    catalog: str
    motor: str
    propeller: str
    esc: str
    esc_mode: str
    battery: str


@dataclass(frozen=True)
class CalibrationSite:
    """The rig file's ``[calibration]``: the site's gravity (latitude and height, or a
    measured g) and a sensor calibration's acceptance limits and validity."""

    latitude_deg: float | None = None
    height_m: float = 0.0
    g_m_s2: float | None = None
    nonlinearity_max_pct: float = 0.5
    hysteresis_max_pct: float = 0.5
    validity_days: float = 180.0


@dataclass(frozen=True)
class EscConfig:
    """ESC input protocol: PWM frame rate and pulse widths (us)."""

    frame_rate_hz: float = 400.0
    idle_us: float = 1000.0
    min_us: float = 1000.0
    max_us: float = 2000.0
    arm_us: float = 1000.0
    timeout_s: float = 0.5  # the ESC's own failsafe: no command for this long -> idle


@dataclass(frozen=True)
class SimConfig:
    """Settings of the simulated rig: seed, ESC scheme, noise, parameter overrides."""

    seed: int = 0
    esc_mode: str = "complementary"
    noise: bool = True
    plant: Mapping[str, float] = field(default_factory=dict)  # PlantParams overrides
    sensors: Mapping[str, float] = field(default_factory=dict)  # SensorParams overrides


@dataclass(frozen=True)
class ThrustMap:
    """Static thrust against command, measured by a slow sweep (Paper C section 4.4)."""

    command_us: tuple[float, ...]
    thrust_n: tuple[float, ...]
    path: Path | None = None

    def command_for(self, thrust_n: float | np.ndarray) -> np.ndarray | float:
        """ESC command that gives ``thrust_n`` in steady state (monotone interpolation)."""
        cmd = np.asarray(self.command_us)
        thr = np.maximum.accumulate(np.asarray(self.thrust_n))  # enforce monotone
        keep = np.concatenate(([True], np.diff(thr) > 0))
        thr, cmd = thr[keep], cmd[keep]
        t = np.asarray(thrust_n, dtype=float)
        if np.any(t < thr[0]) or np.any(t > thr[-1]):
            raise ThrustOutsideMap(
                f"{self.path or 'thrust map'}: thrust {thrust_n} N outside the measured "
                f"range {thr[0]:.3f}-{thr[-1]:.3f} N", float(thr[0]), float(thr[-1]))
        out = np.interp(t, thr, cmd)
        return float(out) if out.ndim == 0 else out

    def thrust_for(self, command_us: float | np.ndarray) -> np.ndarray | float:
        out = np.interp(np.asarray(command_us, dtype=float), self.command_us, self.thrust_n)
        return float(out) if out.ndim == 0 else out


def _device(top: RigTable, role: str) -> DeviceConfig:
    def sim_problem(url: str) -> str | None:
        if urlsplit(url).netloc not in ("", role):
            return f"{url!r}: a sim device for role {role!r} must be sim://{role}"
        return None

    return parse_device(top, role, keys=("channel", "calibration", "options"),
                        scheme_of=lambda url: urlsplit(url).scheme, sim_problem=sim_problem)


#: The largest limit a rig file may set, far beyond any stand the bench drives (the
#: biggest commercial thrust stands: 1.5 kN, 300 A, 100 V, 60 000 rpm). A limit above it
#: switches the check off in effect (``thrust_n = 1e308`` never trips): a typo, refused.
LIMIT_MAXIMA = {"thrust_n": 5000.0, "current_a": 1000.0, "rpm": 200_000.0,
                "voltage_min_v": 1000.0, "voltage_max_v": 1000.0, "temperature_c": 300.0}


def _limits(path: Path, t: RigTable) -> Limits:
    t.only(*(f.name for f in fields(Limits) if f.name != "source"))
    hi = LIMIT_MAXIMA
    vals = {
        "thrust_n": t.number("thrust_n", required=True, lo=0.0, hi=hi["thrust_n"], unit="N"),
        "current_a": t.number("current_a", required=True, lo=0.0, hi=hi["current_a"],
                              unit="A"),
        "rpm": t.number("rpm", required=True, lo=0.0, hi=hi["rpm"], unit="rpm"),
        "voltage_min_v": t.number("voltage_min_v", required=True, lo=0.0,
                                  hi=hi["voltage_min_v"], unit="V"),
        "voltage_max_v": t.number("voltage_max_v", required=True, lo=0.0,
                                  hi=hi["voltage_max_v"], unit="V"),
        "temperature_c": t.number("temperature_c", None, lo=-50.0, hi=hi["temperature_c"],
                                  unit="C"),
    }
    for key in ("thrust_n", "current_a", "rpm", "voltage_max_v"):
        if vals[key] == 0:  # idle already reaches 0: every run would arm, then trip at t = 0
            t.fail(key, "0: expected a limit > 0 (the idle reading already reaches 0, so "
                        "every run would trip at t = 0)")
    if vals["voltage_min_v"] >= vals["voltage_max_v"]:  # type: ignore[operator]
        t.fail("voltage_min_v", f"{vals['voltage_min_v']} V must be below voltage_max_v "
                                f"{vals['voltage_max_v']} V")
    return Limits(**vals, source=str(path))  # type: ignore[arg-type]


def _calibration(t: RigTable | None) -> CalibrationSite:
    """``[calibration]``: where the bench stands (local g) and what a sensor calibration
    must meet to be accepted (fractions in per cent of full scale), and for how long."""
    if t is None:
        return CalibrationSite()
    t.only(*(f.name for f in fields(CalibrationSite)))
    d = CalibrationSite()
    return CalibrationSite(
        latitude_deg=t.number("latitude_deg", None, lo=-90.0, hi=90.0, unit="deg"),
        height_m=t.number("height_m", d.height_m, lo=-500.0, hi=9000.0, unit="m"),
        g_m_s2=t.number("g_m_s2", None, lo=9.7, hi=9.9, unit="m/s^2"),
        nonlinearity_max_pct=t.number("nonlinearity_max_pct", d.nonlinearity_max_pct,
                                      lo=0.0, hi=100.0, unit="%"),
        hysteresis_max_pct=t.number("hysteresis_max_pct", d.hysteresis_max_pct, lo=0.0,
                                    hi=100.0, unit="%"),
        validity_days=t.number("validity_days", d.validity_days, lo=1.0, hi=3650.0,
                               unit="days"))


def _esc(t: RigTable | None) -> EscConfig:
    if t is None:
        return EscConfig()
    t.only(*(f.name for f in fields(EscConfig)))
    lo_us, hi_us = PULSE_RANGE_US
    d = EscConfig()
    cfg = EscConfig(
        frame_rate_hz=t.number("frame_rate_hz", d.frame_rate_hz, lo=FRAME_RATE_RANGE_HZ[0],
                               hi=FRAME_RATE_RANGE_HZ[1], unit="Hz"),
        idle_us=t.number("idle_us", d.idle_us, lo=lo_us, hi=hi_us, unit="us"),
        min_us=t.number("min_us", d.min_us, lo=lo_us, hi=hi_us, unit="us"),
        max_us=t.number("max_us", d.max_us, lo=lo_us, hi=hi_us, unit="us"),
        arm_us=t.number("arm_us", d.arm_us, lo=lo_us, hi=hi_us, unit="us"),
        timeout_s=t.number("timeout_s", d.timeout_s, lo=0.01, hi=60.0, unit="s"),
    )
    if cfg.min_us >= cfg.max_us:
        t.fail("min_us", f"{cfg.min_us} us must be below max_us {cfg.max_us} us")
    for key in ("idle_us", "arm_us"):
        v = getattr(cfg, key)
        if not cfg.min_us <= v <= cfg.max_us:
            t.fail(key, f"{v} us outside min_us-max_us ({cfg.min_us:g}-{cfg.max_us:g} us)")
    return cfg


def _sim(t: RigTable | None, esc_mode: str) -> SimConfig:
    from drivers.sim.plant import PlantParams
    from drivers.sim.sensor_params import SensorParams

    if t is None:
        return SimConfig(esc_mode=esc_mode)
    t.only("seed", "esc_mode", "noise", "plant", "sensors")
    seed = t.number("seed", 0.0, lo=0.0, hi=2**63)
    if seed != int(seed):
        t.fail("seed", f"expected a whole number, got {seed}")
    mode = t.text("esc_mode", esc_mode)
    if mode not in ESC_MODES:
        t.fail("esc_mode", f"{mode!r}: expected one of {', '.join(ESC_MODES)}")
    overrides: dict[str, dict[str, float]] = {}
    for key, cls in (("plant", PlantParams), ("sensors", SensorParams)):
        sub = t.table(key, required=False)
        overrides[key] = {}
        if sub is None:
            continue
        names = [f.name for f in fields(cls)]
        sub.only(*names)
        for name in sub.data:
            default = getattr(cls(), name)
            if isinstance(default, bool):
                overrides[key][name] = sub.flag(name, default)
            else:
                overrides[key][name] = sub.number(name, lo=0.0)  # type: ignore[assignment]
    return SimConfig(int(seed), mode, t.flag("noise", True),  # type: ignore[arg-type]
                     overrides["plant"], overrides["sensors"])


def _components(path: Path, t: RigTable) -> Components:
    keys = [f.name for f in fields(Components)]
    t.only(*keys)
    comp = Components(**{k: t.text(k) for k in keys})
    if comp.esc_mode not in ESC_MODES:
        t.fail("esc_mode", f"{comp.esc_mode!r}: expected one of {', '.join(ESC_MODES)}")
    cat_dir = CATALOGS / comp.catalog
    for key, csv_name in (("motor", "motors.csv"), ("propeller", "propellers.csv"),
                          ("battery", "batteries.csv")):
        table = cat_dir / csv_name
        if not table.is_file():
            continue  # catalog without such a table (or not shipped): ids are free text
        with table.open(newline="", encoding="utf-8") as fh:
            ids = {row.get("id", "") for row in csv.DictReader(fh)}
        if getattr(comp, key) not in ids:
            t.fail(key, f"{getattr(comp, key)!r} is not an id in {table} "
                        f"(expected one of {', '.join(sorted(ids))})")
    return comp


def make_thrust_map(where: Path | str, command_us: Sequence[float], thrust_n: Sequence[float],
                     path: Path | None) -> ThrustMap:
    cmd = np.asarray(command_us, dtype=float)
    thr = np.asarray(thrust_n, dtype=float)
    if cmd.ndim != 1 or cmd.shape != thr.shape or cmd.size < 2:
        raise RigError(f"{where}: thrust map needs two equal-length columns of >= 2 values "
                       f"(got {cmd.shape} and {thr.shape})")
    if not (np.all(np.isfinite(cmd)) and np.all(np.isfinite(thr))):
        raise RigError(f"{where}: thrust map holds non-finite values")
    if np.any(np.diff(cmd) <= 0):
        raise RigError(f"{where}: thrust map command_us must increase strictly")
    return ThrustMap(tuple(cmd.tolist()), tuple(thr.tolist()), path)


def read_thrust_map(path: Path) -> ThrustMap:
    check_input(path, "thrust map")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise RigError(f"{path}: cannot read thrust map: {exc}") from None
    reader = csv.DictReader(io.StringIO(text))
    names = [n.strip() for n in reader.fieldnames or []]
    if twice := sorted({n for n in names if n and names.count(n) > 1}):
        raise RigError(f"{path}: the header names column {twice[0]!r} twice; rename one")
    rows = list(reader)
    if not rows or not {"command_us", "thrust_n"} <= set(rows[0]):
        raise RigError(f"{path}: thrust map needs columns command_us,thrust_n")
    cmd, thr = [], []
    for i, row in enumerate(rows, start=2):
        try:
            cmd.append(float(row["command_us"]))
            thr.append(float(row["thrust_n"]))
        except (TypeError, ValueError):
            raise RigError(f"{path}: row {i}: expected numbers in command_us,thrust_n, "
                           f"got {row}") from None
    return make_thrust_map(path, cmd, thr, path)


def _check_devices(path: Path, devices: Mapping[str, DeviceConfig]) -> None:
    """Calibrations and options as the device openers will take them, checked now: a bad
    one must stop the command before a run folder exists, naming file, table and key."""
    from drivers.errors import DeviceError
    from drivers.factory import validate_device

    for role, dev in devices.items():
        try:
            validate_device(path, role, dev)
        except DeviceError as exc:
            raise RigError(str(exc)) from None


def parse(path: Path, top: RigTable) -> dict[str, Any]:
    """A propulsion rig file's tables as the fields of :class:`bench.rig.rig.RigConfig`."""
    top.only("rig", "devices", "limits", "components", "esc", "sim", "thrust_map",
             "calibration")
    rig = top.table("rig")
    assert rig is not None
    rig.only("name", "description")
    name = rig.text("name")
    devices_t = top.table("devices")
    assert devices_t is not None
    devices_t.only(*ROLES)
    for role in ROLES:
        if role not in devices_t.data:
            devices_t.fail(role, f"missing device; a rig needs {', '.join(ROLES)}")
    devices = {role: _device(devices_t, role) for role in ROLES}
    _check_devices(path, devices)
    limits = _limits(path, top.table("limits"))  # type: ignore[arg-type]
    components = _components(path, top.table("components"))  # type: ignore[arg-type]
    esc = _esc(top.table("esc", required=False))
    calibration = _calibration(top.table("calibration", required=False))
    sim = _sim(top.table("sim", required=False), components.esc_mode)
    tm_path: Path | None = None
    thrust_map: ThrustMap | None = None
    tm = top.table("thrust_map", required=False)
    if tm is not None:
        tm.only("file")
        tm_path = check_input(path.parent / tm.text("file"), "thrust map").resolve()
        if tm_path.is_file():
            thrust_map = read_thrust_map(tm_path)
    return {"path": path, "name": name, "devices": devices, "limits": limits,
            "components": components, "esc": esc, "sim": sim, "thrust_map": thrust_map,
            "thrust_map_path": tm_path, "description": rig.text("description", ""),
            "calibration": calibration}
