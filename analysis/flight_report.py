"""What a flight log says about the vehicle that flew it: the step response per axis,
each motor's in-flight response, the hover, and the gyro noise against throttle.

Works on any run of kind ``flight`` (``rotorbench import`` of a blackbox, ULog or
DataFlash log; columns as docs/flight-logs.md lists them) and on nothing else: the design
it is compared with, and the bench's constants, come from the command.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.errors import LogError
from analysis.flight_noise import NoiseMap, gyro_noise_vs_throttle
from analysis.flight_response import AxisResponse, flight_step_responses
from analysis.motor_response import MotorResponse, fit_motor_response
from analysis.run_record import RunRecord

__all__ = ["FlightReport", "flight_report", "hover_summary", "throttle_of"]

AXES = ("x", "y", "z")
HOVER_RATE_RAD_S = 0.5  # hovering: every body rate below this
HOVER_MIN_S = 2.0


@dataclass(frozen=True)
class FlightReport:
    run_id: str
    responses: dict[str, AxisResponse]
    motors: dict[str, MotorResponse]
    hover: dict[str, float]
    noise: NoiseMap | None
    notes: list[str]

    def summary(self) -> dict[str, Any]:
        return {"run": self.run_id,
                "step_response": {a: r.summary() for a, r in self.responses.items()},
                "motors": {m: r.summary() for m, r in self.motors.items()},
                "hover": self.hover,
                "noise_peaks": {a: self.noise.peaks(a) for a in self.noise.psd}
                if self.noise is not None else {},
                "notes": self.notes}


def _col(rec: RunRecord, name: str) -> np.ndarray | None:
    return rec.samples[name].to_numpy(dtype=float) if name in rec.samples.columns else None


def _motor_names(rec: RunRecord) -> list[str]:
    found = {int(m.group(1)) for c in rec.samples.columns
             if (m := re.fullmatch(r"motor(\d+)_norm", str(c)))}
    return [f"motor{i}" for i in sorted(found)]


def throttle_of(rec: RunRecord) -> np.ndarray | None:
    """The throttle 0..1: the logged stick (blackbox ``throttle_norm``), else the mean of
    the motors' normalised outputs (what the mixer made of it)."""
    thr = _col(rec, "throttle_norm")
    if thr is not None and np.isfinite(thr).any():
        return thr
    motors = [c for m in _motor_names(rec) if (c := _col(rec, f"{m}_norm")) is not None]
    if not motors:
        return None
    with np.errstate(invalid="ignore"):
        return np.nanmean(np.vstack(motors), axis=0)


def hover_summary(rec: RunRecord, thr: np.ndarray | None, gyro: dict[str, np.ndarray]
                  ) -> dict[str, float]:
    """Median throttle, current, voltage and power over the samples where the vehicle
    flies (throttle above a third of its top, at least 0.1: idle on the ground is out),
    every body rate is small and the throttle is inside the flight's middle 80 % (climbs
    and descents out). ``thr`` is ``throttle_of(rec)``, ``gyro`` the body rates by axis:
    the report has read them already."""
    t = rec.column("t_s")
    if thr is None or not gyro:
        return {}
    calm = np.all(np.abs(np.vstack(list(gyro.values()))) < HOVER_RATE_RAD_S, axis=0)
    if not np.isfinite(thr).any():
        return {"hover_s": 0.0}
    flying = np.isfinite(thr) & (thr > max(0.1, np.nanpercentile(thr, 95) / 3))
    if not flying.any():
        return {"hover_s": 0.0}
    lo, hi = np.nanpercentile(thr[flying], [10, 90])
    mask = calm & flying & (thr >= lo) & (thr <= hi)
    span = float(np.sum(np.diff(t)[mask[:-1]])) if t.size > 1 else 0.0
    if span < HOVER_MIN_S:
        return {"hover_s": span}
    out = {"hover_s": span, "throttle": float(np.nanmedian(thr[mask]))}
    v, i = _col(rec, "voltage_v"), _col(rec, "current_a")
    if v is not None and np.isfinite(v[mask]).any():
        out["voltage_v"] = float(np.nanmedian(v[mask]))
    if i is not None and np.isfinite(i[mask]).any():
        out["current_a"] = float(np.nanmedian(i[mask]))
        if v is not None:
            out["power_w"] = float(np.nanmedian((v * i)[mask]))
    return out


def flight_report(rec: RunRecord) -> FlightReport:
    """The report of one flight run (``LogError`` for a run that is not a flight)."""
    if rec.meta.get("kind") != "flight":
        raise LogError(f"{rec.path}: a run of kind {rec.meta.get('kind')!r}; flight-report "
                       "reads flight logs (rotorbench import LOG)")
    t = rec.column("t_s")
    notes: list[str] = []
    setpoint = {a: c for a in AXES if (c := _col(rec, f"rate_sp_{a}_rad_s")) is not None}
    gyro = {a: c for a in AXES if (c := _col(rec, f"gyro_{a}_rad_s")) is not None}
    pairs = [a for a in AXES if a in setpoint and a in gyro]
    if not pairs:
        notes.append("no rate setpoint and gyro of one axis: no step response")
    responses = flight_step_responses(t, {a: setpoint[a] for a in pairs},
                                      {a: gyro[a] for a in pairs}) if pairs else {}
    rpms = {m: w for m in _motor_names(rec) if (w := _col(rec, f"{m}_rpm")) is not None}
    motors: dict[str, MotorResponse] = {}
    for m, w in rpms.items():
        u = _col(rec, f"{m}_norm")
        if u is not None and np.isfinite(w).any():
            motors[m] = fit_motor_response(t, u, w, m)
    if not motors:
        notes.append("no motor speed in the log (bidirectional DShot eRPM, ESC telemetry): "
                     "no in-flight motor response")
    thr = throttle_of(rec)
    with warnings.catch_warnings():  # a row with no motor's speed (a hole) is NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        rpm = np.nanmean(np.vstack(list(rpms.values())), axis=0) if rpms else None
    noise = gyro_noise_vs_throttle(t, gyro, thr, rpm) if thr is not None and gyro else None
    hover = hover_summary(rec, thr, gyro)
    if "throttle" not in hover:
        notes.append(f"no hover of {HOVER_MIN_S:g} s (body rates below "
                     f"{HOVER_RATE_RAD_S:g} rad/s at a mid throttle)")
    return FlightReport(rec.id, responses, motors, hover, noise, notes)
