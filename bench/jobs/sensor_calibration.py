"""Run a calibration series on an opened stand and record it as a run of kind
``calibration``: every reading of every hold kept (samples), one event per step, the
fitted calibration record in ``run.json`` (``calibration``) and its figure
(``calibration.png``). A calibration is a run like
any other, so the folder store, the lab catalog and the web view keep it as they keep runs:
versioned by its id, never overwritten.

The ESC is never armed: the rig opens disarmed and closes idle and disarmed.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np

from analysis.metrology.calibration_figure import plot_calibration
from analysis.metrology.force_calibration import (
    CalibrationPoint,
    ForceCalibration,
    fit_force_calibration,
)
from analysis.metrology.gum import rectangular
from analysis.metrology.reference_force import Gravity, conventional_weight_force, local_gravity
from bench.engine.recorder import RunRecorder, utc_now
from bench.errors import RigError
from bench.jobs.weight_loaders import Loader
from bench.plans.weight_series import CELLS, SEQUENCE, CalibrationPlan
from bench.rig.rig_propulsion import CalibrationSite
from bench.store.indexed_run import indexed_run

__all__ = ["Acceptance", "CalibrationOutcome", "run_sensor_calibration", "site_references"]

#: The figure of the calibration, in its run folder.
FIGURE = "calibration.png"
#: A read of the cell while a step settles or holds: often enough for any driver's buffer.
POLL_S = 0.05
#: A hold ends this close to its end: below any clock's resolution that matters here.
END_TOLERANCE_S = 1e-9
#: Buoyancy: the air's density is not measured; 1.2 kg/m^3 +-10 % (sea level to 1000 m,
#: 0-30 degC) on weights of 8000 kg/m^3 puts +-1.5e-5 on the force (OIML D 28).
BUOYANCY_U_REL = rectangular(0.1 * 1.2 / 8000.0)


@dataclass(frozen=True)
class Acceptance:
    """The rig file's acceptance limits (fractions of full scale) and validity period."""

    nonlinearity: float = 0.005
    hysteresis: float = 0.005
    validity_days: float = 180.0

    def limits(self) -> dict[str, float]:
        return {"nonlinearity": self.nonlinearity, "hysteresis": self.hysteresis}


def site_references(site: CalibrationSite) -> tuple[Gravity, Acceptance]:
    """The rig file's ``[calibration]`` as the job takes it: local g, acceptance limits."""
    return (local_gravity(site.latitude_deg, site.height_m, site.g_m_s2),
            Acceptance(site.nonlinearity_max_pct / 100, site.hysteresis_max_pct / 100,
                       site.validity_days))


@dataclass
class CalibrationOutcome:
    run_dir: Path
    fit: ForceCalibration
    record: dict[str, Any]


def _sensor_for(rig: Any, channel: str) -> tuple[str, Any]:
    """The opened sensor that reports ``channel`` (a torque cell may be its own device)."""
    for role, sensor in rig.sensors.items():
        if channel in {c.name for c in sensor.describe().channels}:
            return role, sensor
    raise RigError(f"this rig has no sensor reporting {channel} (its sensors: "
                   f"{', '.join(rig.sensors)})")


def run_sensor_calibration(rig_cfg: Any, rig: Any, plan: CalibrationPlan, loader: Loader,
                           gravity: Gravity, out: Path, *, acceptance: Acceptance,
                           meta: dict[str, Any] | None = None,
                           on_step: Callable[[int, int, str], None] | None = None
                           ) -> CalibrationOutcome:
    """The whole series on ``rig`` (opened, ESC disarmed), recorded under ``out``."""
    channel = CELLS[plan.cell][1]
    role, sensor = _sensor_for(rig, channel)
    clock = rig.clock
    run_meta = {"kind": "calibration", "rig": rig_cfg.name, "sequence": SEQUENCE,
                "plan": plan.as_dict(), **(meta or {})}
    with indexed_run(out, f"calibration-{plan.cell}", run_meta,
                     base_columns=("t_s", channel, "reference", "step")) as recorder:
        try:
            points = _series(clock, sensor, role, channel, plan, loader, gravity, recorder,
                             on_step)
            fit = fit_force_calibration(points, u_rel_systematic=math.hypot(
                gravity.u / gravity.g, BUOYANCY_U_REL, _u_arm_rel(plan)),
                systematic_note=f"g {gravity.g:.5f} m/s^2 ({gravity.source}), buoyancy"
                                + (f", arm {plan.arm_m:g} m" if plan.arm_m else ""))
        except BaseException as exc:
            recorder.finish("fail", f"calibration stopped: {exc}" if str(exc)
                            else "calibration stopped")
            raise
        record = _record(role, sensor, channel, plan, gravity, fit, acceptance,
                         recorder.run_dir.name, rig_cfg.name, recorder.meta)
        failed = record["acceptance"]["failed"]
        plot_calibration(record, recorder.run_dir / FIGURE)
        recorder.finish("success", "calibration accepted" if not failed else
                        "calibration outside its acceptance limits: " + "; ".join(failed),
                        calibration=record)
    return CalibrationOutcome(recorder.run_dir, fit, record)


def _series(clock: Any, sensor: Any, role: str, channel: str, plan: CalibrationPlan,
            loader: Loader, gravity: Gravity, recorder: RunRecorder,
            on_step: Callable[[int, int, str], None] | None) -> list[CalibrationPoint]:
    """Each weight on, settled, held and recorded: the points of the fit."""
    steps = plan.steps()
    points: list[CalibrationPoint] = []
    t0 = clock.now()
    for i, (mass, direction) in enumerate(steps, start=1):
        force = _reference(plan, mass, gravity)
        loader.load(force, mass, i, len(steps))
        sensor.read_block()  # what came while the weight went on is not part of the hold
        recorder.event(clock.now() - t0, "step", i, f"{mass * 1e3:g} g {direction}")
        _read_for(clock, sensor, channel, plan.settle_s)
        t, y = _read_for(clock, sensor, channel, plan.hold_s)
        if t.size < 2:
            raise RigError(f"{role}: {t.size} readings in a {plan.hold_s:g} s hold")
        recorder.append({"t_s": t - t0, channel: y, "reference": np.full(t.size, force),
                         "step": np.full(t.size, float(i))})
        points.append(CalibrationPoint(force, _u_force_independent(plan, mass, gravity),
                                       direction, t - t0, y))
        if on_step is not None:
            on_step(i, len(steps), f"{mass * 1e3:g} g {direction}: "
                                   f"{float(np.mean(y)):.5g} {channel}")
    return points


def _reference(plan: CalibrationPlan, mass: float, gravity: Gravity) -> float:
    """The force (N) or torque (N m) the weight puts on the cell."""
    force = conventional_weight_force(mass, gravity.g)
    return force * plan.arm_m if plan.cell == "torque" and plan.arm_m else force


def _u_force_independent(plan: CalibrationPlan, mass: float, gravity: Gravity) -> float:
    """The weight's own part of its force's uncertainty (each weight errs on its own)."""
    u = plan.mass_u(mass) * gravity.g
    return u * plan.arm_m if plan.cell == "torque" and plan.arm_m else u


def _u_arm_rel(plan: CalibrationPlan) -> float:
    return plan.arm_u_m / plan.arm_m if plan.cell == "torque" and plan.arm_m else 0.0


def _read_for(clock: Any, sensor: Any, channel: str, seconds: float
              ) -> tuple[np.ndarray, np.ndarray]:
    """Every reading of ``channel`` for ``seconds`` of the rig's clock. Ends within
    ``END_TOLERANCE_S`` of the end: a simulated clock counts whole nanoseconds, so a float
    end can stay a fraction of one ahead, and sleeping that rounds to nothing."""
    ts, ys = [], []
    end = clock.now() + seconds
    while True:
        clock.sleep(min(POLL_S, max(0.0, end - clock.now())))
        block = sensor.read_block()
        if block.t_s.size:
            ts.append(np.asarray(block.t_s, dtype=float))
            ys.append(np.asarray(block.values[channel], dtype=float))
        if clock.now() >= end - END_TOLERANCE_S:
            break
    if not ts:
        return np.empty(0), np.empty(0)
    return np.concatenate(ts), np.concatenate(ys)


def _record(role: str, sensor: Any, channel: str, plan: CalibrationPlan, gravity: Gravity,
            fit: ForceCalibration, acceptance: Acceptance, run_id: str, rig_name: str,
            meta: dict[str, Any]) -> dict[str, Any]:
    """The calibration record (ISO/IEC 17025 7.8 and 6.4.13: what, when, who, with what,
    the results with their uncertainty, the acceptance and the next due date)."""
    now = datetime.now(UTC)
    info = sensor.describe()
    failed = fit.failed(acceptance.limits())
    return {
        "id": run_id,
        "bench": meta.get("bench") or rig_name,
        "rig": rig_name,
        "sensor": {"role": role, "channel": channel, "url": info.url, "model": info.model},
        "date_utc": utc_now(),
        "valid_until_utc": (now + timedelta(days=acceptance.validity_days)).strftime(
            "%Y-%m-%dT%H:%M:%SZ"),
        "operator": meta.get("operator"),
        "method": "up/down series of dead weights (ISO 376 scaled), weighted least squares, "
                  "GUM budget",
        "masses": [{"nominal_kg": m, "u_kg": plan.mass_u(m),
                    "class": plan.weight_class if plan.mass_u_kg is None else None}
                   for m in plan.masses_kg],
        "gravity": {"g_m_s2": gravity.g, "u_m_s2": gravity.u, "source": gravity.source},
        "arm_m": plan.arm_m, "arm_u_m": plan.arm_u_m if plan.arm_m else None,
        "plan": plan.as_dict(),
        "result": fit.as_dict(),
        "applies": {"channel": channel, "gain": fit.scale, "offset": fit.offset,
                    "u_gain_rel": fit.scale_budget.u,
                    "rule": f"{channel} = gain x (reading - offset)"},
        "acceptance": {"limits_fraction_of_full_scale": acceptance.limits(),
                       "passed": not failed, "failed": failed},
        "software_version": meta.get("software_version"),
    }
