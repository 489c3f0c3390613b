"""The uncertainty sidecar of an export: each exported constant's value, u, U, k, dof_eff,
budget terms and the run and calibration records it came from.

Why: an autopilot's parameter file has no room for an uncertainty, yet a model fed from
it should know how far to trust each number; the sidecar keeps them beside the file.
Parameters without a budget (ArduPilot's and PX4's thrust-curve shapes, Gazebo's moment
constant, a ratio whose terms are correlated) are listed as such, not left out silently.
"""

from __future__ import annotations

from typing import Any

from analysis.exports import GazeboFits, gazebo_fits
from analysis.metrology.constant_budgets import (
    entry,
    static_budgets,
    step_budgets,
    tare_uncertainty,
)
from analysis.run_record import RunRecord

__all__ = ["export_uncertainties"]

#: exported parameter -> the budgeted constant it is
GAZEBO = {"motorConstant": "k_f_n_s2", "timeConstantUp": "tau_up_s",
          "timeConstantDown": "tau_down_s"}


def _calibration_ids(record: RunRecord, channel: str) -> list[str]:
    cal = (record.meta.get("calibrations") or {}).get(channel) or {}
    return [str(cal["id"])] if cal.get("id") and "gain" in cal else []


def export_uncertainties(target: str, params: dict[str, Any], record: RunRecord,
                         thrust_record: RunRecord | None = None,
                         step_record: RunRecord | None = None,
                         fits: GazeboFits | None = None) -> dict[str, Any]:
    """The sidecar of ``params`` (``analysis.exports.export_params``' result); ``fits``:
    the Gazebo fits those parameters came from, when the caller has them."""
    constants: dict[str, Any] = {}
    if target == "gazebo":
        fits = fits or gazebo_fits(record, thrust_record, step_record)
        static_rec = thrust_record or record
        b = static_budgets(fits.static, static_rec.meta.get("calibrations") or {},
                           tare_uncertainty(static_rec.meta))
        if "k_f_n_s2" in b:
            constants["motorConstant"] = entry(b["k_f_n_s2"], static_rec.id,
                                               _calibration_ids(static_rec, "thrust_n"))
        if step_record is not None and fits.step is not None:
            sb = step_budgets(fits.step)
            for name in ("timeConstantUp", "timeConstantDown"):
                if GAZEBO[name] in sb:
                    constants[name] = entry(sb[GAZEBO[name]], step_record.id)
    skip = {"notes", "target", "run", "command_axis"}
    without = sorted(k for k, v in params.items()
                     if k not in constants and k not in skip and isinstance(v, int | float))
    return {"target": target, "run": record.id, "constants": constants,
            "without_budget": without}
