"""A stand's runs apply its newest calibration: raw readings to newtons, with the record's
id in ``run.json``.

The newest calibration run of the rig (by name) for each calibrated channel in the runs
root is looked up when a run opens its devices. Accepted and in date: applied. Expired:
applied, with a warning. Outside its acceptance limits, or made on another sensor (its
model or address differ from the opened one's: the cell was swapped or moved): the run is
refused unless the operator accepts an uncalibrated run (``--accept-uncalibrated``), and
then nothing is applied. None at all: a real stand warns (its cells read through their datasheet
scale); a simulated one says nothing (its cells are what the rig file says).
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from bench.errors import RigError
from bench.plans.weight_series import CELLS, SEQUENCE
from bench.store.run_index import INDEX_NAME, RunIndex
from bench.store.run_summary import RunFilter

__all__ = ["AppliedCalibration", "CalibratedSensor", "apply_calibrations",
           "declared_cell_dynamics", "newest_records"]

log = logging.getLogger(__name__)

#: the channels a calibration corrects
CHANNELS = frozenset(channel for _role, channel in CELLS.values())


def newest_records(out_root: Path, rig_name: str) -> dict[str, dict[str, Any]]:
    """The newest calibration record of ``rig_name`` per channel, from the run index (the
    successful calibration runs only, newest first, until every channel has one)."""
    if not (Path(out_root) / INDEX_NAME).exists():
        return {}
    index = RunIndex(out_root, read_only=True)
    found: dict[str, dict[str, Any]] = {}
    for row in index.select(RunFilter(status="success", sequence=SEQUENCE), newest_first=True):
        if row.rig != rig_name:
            continue
        folder = index.folder(row.path)
        try:
            record = json.loads((folder / "run.json").read_text())["calibration"]
        except (OSError, ValueError, KeyError, TypeError):
            continue  # a calibration run without its record: not one to apply
        if isinstance(record, dict):
            found.setdefault(str(record["applies"]["channel"]), record)
            if found.keys() >= CHANNELS:
                break
    return found


@dataclass(frozen=True)
class AppliedCalibration:
    """What a run applied to one channel, as ``run.json`` keeps it."""

    channel: str
    id: str
    gain: float
    offset: float
    u_gain_rel: float
    valid_until_utc: str
    state: str  # "valid", "expired" or "not accepted (run accepted uncalibrated)"
    budget: dict[str, Any] | None = None  # the record's scale budget (relative), by term

    def as_dict(self) -> dict[str, Any]:
        return {"id": self.id, "gain": self.gain, "offset": self.offset,
                "u_gain_rel": self.u_gain_rel, "valid_until_utc": self.valid_until_utc,
                "state": self.state, "budget": self.budget}


class CalibratedSensor:
    """A sensor whose channel reads through a calibration: ``gain x (reading - offset)``."""

    def __init__(self, sensor: Any, applied: AppliedCalibration) -> None:
        self.sensor = sensor
        self.applied = applied

    def describe(self) -> Any:
        return self.sensor.describe()

    def read_block(self) -> Any:
        block = self.sensor.read_block()
        ch = self.applied.channel
        if ch not in block.values:
            return block
        values = dict(block.values)
        values[ch] = self.applied.gain * (np.asarray(values[ch]) - self.applied.offset)
        return replace(block, values=values)

    def close(self) -> None:
        self.sensor.close()

    def __getattr__(self, name: str) -> Any:  # the wrapped device's own surface
        return getattr(self.sensor, name)


def apply_calibrations(rig_cfg: Any, devices: Any, out_root: Path, *,
                       accept_uncalibrated: bool = False) -> dict[str, dict[str, Any]]:
    """Wrap each calibrated sensor of the opened ``devices``; what was applied, by channel
    (for ``run.json``). Refuses (``RigError``) a record outside its acceptance limits
    unless ``accept_uncalibrated``."""
    records = newest_records(out_root, rig_cfg.name)
    applied: dict[str, dict[str, Any]] = {}
    for role, sensor in list(devices.sensors.items()):
        real = not _simulated(rig_cfg, role)
        channels = {c.name for c in sensor.describe().channels}
        for channel in sorted(channels & CHANNELS):
            record = records.get(channel)
            if record is None:
                if real:
                    log.warning("%s: no calibration of %s in %s: it reads through the rig "
                                "file's scale (rotorbench calibrate-sensors)", rig_cfg.name,
                                channel, out_root)
                continue
            other = _other_sensor(record, sensor)
            if other:
                if not accept_uncalibrated:
                    raise RigError(
                        f"{rig_cfg.name}: the newest calibration of {channel} ({record['id']}) "
                        f"is of another sensor ({other}): calibrate this one (rotorbench "
                        "calibrate-sensors), or run with --accept-uncalibrated")
                log.warning("%s: %s runs uncalibrated (--accept-uncalibrated): its newest "
                            "calibration %s is of another sensor (%s)", rig_cfg.name, channel,
                            record["id"], other)
                applied[channel] = {"id": record["id"],
                                    "state": "another sensor's: not applied"}
                continue
            state = _state(record)
            if state == "not accepted":
                if not accept_uncalibrated:
                    raise RigError(
                        f"{rig_cfg.name}: the newest calibration of {channel} "
                        f"({record['id']}) failed its acceptance limits ("
                        + "; ".join(record["acceptance"]["failed"])
                        + "): calibrate again, or run with --accept-uncalibrated")
                log.warning("%s: %s runs uncalibrated (--accept-uncalibrated): its "
                            "calibration %s failed its acceptance limits", rig_cfg.name,
                            channel, record["id"])
                applied[channel] = {"id": record["id"], "state": "not accepted: not applied"}
                continue
            if state == "expired":
                log.warning("%s: the calibration of %s (%s) expired on %s; applied all the "
                            "same: calibrate again", rig_cfg.name, channel, record["id"],
                            record["valid_until_utc"])
            a = record["applies"]
            cal = AppliedCalibration(channel, str(record["id"]), float(a["gain"]),
                                     float(a["offset"]), float(a["u_gain_rel"]),
                                     str(record["valid_until_utc"]), state,
                                     record.get("result", {}).get("scale_budget"))
            devices.sensors[role] = sensor = CalibratedSensor(sensor, cal)
            applied[channel] = cal.as_dict()
    return applied


def _other_sensor(record: dict[str, Any], sensor: Any) -> str:
    """Why ``record`` was made on another sensor than ``sensor`` (its model or address
    differ), or '' when it was made on this one. A record without them is taken as this
    sensor's: there is nothing to tell it by."""
    made = record.get("sensor") or {}
    info = sensor.describe()
    for what in ("model", "url"):
        theirs, ours = made.get(what), getattr(info, what, None)
        if theirs is not None and ours is not None and str(theirs) != str(ours):
            return f"{what} {theirs!r}, this rig's is {ours!r}"
    return ""


def _simulated(rig_cfg: Any, role: str) -> bool:
    """Whether the device of ``role`` is a simulator (``sim://``, or a wire-level one on
    host ``sim``, as beside a real firmware): its cell is what the rig file says."""
    from urllib.parse import urlsplit

    dev = getattr(rig_cfg, "devices", {}).get(role)
    url = str(getattr(dev, "url", ""))
    return url.startswith("sim://") or urlsplit(url).netloc == "sim"


def _state(record: dict[str, Any], now: datetime | None = None) -> str:
    if not record.get("acceptance", {}).get("passed", False):
        return "not accepted"
    until = datetime.strptime(record["valid_until_utc"], "%Y-%m-%dT%H:%M:%SZ").replace(
        tzinfo=UTC)
    return "expired" if (now or datetime.now(UTC)) > until else "valid"


def declared_cell_dynamics(devices: Any) -> dict[str, dict[str, Any]]:
    """The cells' mechanics the opened sensors declare (``describe().extra``
    ``cell_dynamics``: natural frequency, damping ratio), by channel, for ``run.json``."""
    out: dict[str, dict[str, Any]] = {}
    for sensor in devices.sensors.values():
        declared = sensor.describe().extra.get("cell_dynamics")
        if isinstance(declared, dict):
            out.update({str(k): dict(v) for k, v in declared.items() if isinstance(v, dict)})
    return out
