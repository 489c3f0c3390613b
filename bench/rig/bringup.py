"""A bring-up report of any rig (``rotorbench check --deep``): a propulsion stand or an
IMU bench, one device list by role.

Everything at rest (nothing armed, nothing moved): per device its identity and firmware
(what its backend's ``describe()`` reports), the limits the device states against the rig
file's (the hexapod: the motion limits it reports and its controller state, servo,
referenced and travel from ``SVO?``/``FRF?``/``TMN?``/``TMX?``),
the achieved sample rate with missed or late samples (``bench``'s counting rule, here on
the read blocks), the noise floor (mean and RMS about the mean of every column: load
cell N RMS, current offset A) and the clock skew between devices: each sensor's stamp lag
behind the host clock at each read (median), and its difference to the first sensor's.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from bench.engine.drops import DropCounter  # the run's counting rule, the same numbers
from drivers.contracts import Block
from drivers.factory import open_rig

__all__ = ["bringup_report"]


def _identity(info: Any) -> dict[str, Any]:
    keep = ("vendor", "firmware", "variant", "msp_api", "version", "board", "controller_id",
            "esc_index", "node_id", "motor_index", "dead_host_s", "dead_host", "propellers_off",
            "train_pulses", "frame_rate_hz", "rate_hz", "pole_pairs")
    return {"model": info.model, **{k: info.extra[k] for k in keep if k in info.extra}}


def _limits(info: Any, rig_limits: dict[str, float]) -> dict[str, Any]:
    """Per channel: the range the device states (ChannelInfo) and the rig file's limit."""
    out = {}
    for ch in info.channels:
        stated = math.isfinite(ch.low) or math.isfinite(ch.high)
        rig = rig_limits.get(ch.name)
        if stated or rig is not None:
            out[ch.name] = {"device": [ch.low, ch.high] if stated else None, "rig": rig}
    return out


def _stats(blocks: list[Block]) -> dict[str, dict[str, float]]:
    cols: dict[str, list[np.ndarray]] = {}
    for b in blocks:
        for k, v in b.values.items():
            cols.setdefault(k, []).append(np.asarray(v, float))
    out = {}
    for k, parts in cols.items():
        v = np.concatenate(parts)
        v = v[np.isfinite(v)]
        if v.size:
            out[k] = {"mean": float(v.mean()), "rms": float(v.std())}
    return out


def _rig_limits(rig: Any) -> dict[str, float]:
    """The rig file's limits by channel name: the propulsion stand's limits, or the IMU
    bench's datasheet ranges of the IMU under test (the hexapod's limits are reported
    with the hexapod)."""
    imu = getattr(rig, "imu", None)
    if imu is not None and getattr(rig, "hexapod", None) is not None:  # the IMU's ranges
        gyro, acc = imu.value("gyro_range_rad_s"), imu.value("acc_range_m_s2")
        return {f"imu_{kind}_{axis}_{unit}": rng for kind, unit, rng in
                (("gyro", "rad_s", gyro), ("acc", "m_s2", acc)) for axis in "xyz"}
    lim, esc = getattr(rig, "limits", None), getattr(rig, "esc", None)
    if lim is None or esc is None:
        return {}
    return {"thrust_n": lim.thrust_n, "current_a": lim.current_a, "rpm": lim.rpm,
            "voltage_v": lim.voltage_max_v, "throttle_us": esc.max_us}


def _actuator(role: str, dev: Any, rig: Any) -> dict[str, Any]:
    """The ESC or the hexapod: identity and limits, device against rig file."""
    info = dev.describe()
    entry: dict[str, Any] = {"role": role, "url": rig.devices[role].url,
                             "identity": _identity(info)}
    if role == "hexapod":
        stated = dict(info.extra.get("limits") or {})
        file_limits = dict(getattr(getattr(rig, "hexapod", None), "limits", {}) or {})
        entry["limits"] = {k: {"device": stated.get(k), "rig": file_limits.get(k)}
                           for k in sorted(set(stated) | set(file_limits))}
        if "controller" in info.extra:
            entry["controller"] = info.extra["controller"]
    else:
        entry["limits"] = _limits(info, {"throttle_us": rig.esc.max_us})
    return entry


def bringup_report(rig: Any, seconds: float = 2.0) -> dict[str, Any]:
    """Open the rig, listen ``seconds`` at rest, return the report (JSON-ready)."""
    rig_limits = _rig_limits(rig)
    with open_rig(rig) as r:
        actuators = [_actuator(role, r.devices[role], rig)
                     for role in ("esc", "hexapod") if role in r.devices]
        roles = list(r.sensors)
        for role in roles:
            r.sensors[role].read_block()  # what came while opening
        blocks: dict[str, list[Block]] = {role: [] for role in roles}
        lags: dict[str, list[float]] = {role: [] for role in roles}
        drops = DropCounter()
        infos = {role: r.sensors[role].describe() for role in roles}
        for role in roles:
            stated = [c.rate_hz for c in infos[role].channels if c.rate_hz > 0]
            if stated:
                drops.expect(role, max(stated))
        t0 = r.clock.now()
        deadline = time.monotonic() + seconds + 5.0
        while r.clock.now() - t0 < seconds and time.monotonic() < deadline:
            r.clock.sleep(0.02)
            for role in roles:
                b = r.sensors[role].read_block()
                now = r.clock.now()
                if len(b):
                    blocks[role].append(b)
                    lags[role].append(now - float(b.t_s[-1]))
                    drops.update(role, b.t_s, b.values)
        span = max(r.clock.now() - t0, 1e-9)
    summary = drops.summary()["drops"]
    devices = list(actuators)
    ref_lag = None
    for role in roles:
        n = sum(len(b) for b in blocks[role])
        lag = float(np.median(lags[role])) if lags[role] else None
        if ref_lag is None and lag is not None:
            ref_lag = lag
        info = infos[role]
        stated = [c.rate_hz for c in info.channels if c.rate_hz > 0]
        d = summary.get(role, {})
        devices.append({
            "role": role, "url": rig.devices[role].url, "identity": _identity(info),
            "limits": _limits(info, rig_limits),
            "rate_hz": n / span, "stated_rate_hz": max(stated) if stated else None,
            "samples": n, "dropped": d.get("dropped", 0),
            "longest_gap_s": d.get("longest_gap_s"), "noise": _stats(blocks[role]),
            "lag_s": lag, "skew_s": None if lag is None or ref_lag is None else lag - ref_lag})
    return {"rig": str(rig.path), "seconds": seconds, "devices": devices}
