"""A load-cell calibration from the console: the bench side of the Devices tab's
"Calibrate load cell". The same job as ``rotorbench calibrate-sensors``
(``bench.jobs.sensor_calibration``); the operator is the window: each weight is asked for
with a ``cell_prompt`` message and confirmed with the "Weight placed" button, or the
simulated stand's fixture places it. Stop (Esc) ends it at the next prompt, recorded as
failed; the ESC is never armed."""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bench.errors import RigError
from bench.jobs.weight_loaders import sim_fixture, weight_prompt
from bench.plans.weight_series import CalibrationPlan, parse_masses_g

__all__ = ["CellCalibration", "plan_of"]


def plan_of(spec: dict[str, Any]) -> CalibrationPlan:
    """The window's request as a plan: masses (grams, text), class, hold; the plan's own
    defaults for what it leaves out."""
    kw: dict[str, Any] = {}
    if spec.get("masses_g"):
        kw["masses_kg"] = parse_masses_g(str(spec["masses_g"]))
    if spec.get("weight_class"):
        kw["weight_class"] = str(spec["weight_class"])
    if spec.get("hold_s") is not None:
        kw["hold_s"] = float(spec["hold_s"])
    return CalibrationPlan(**kw)


class CellCalibration:
    """One calibration on the bench's worker thread; ``placed()`` is the window's answer."""

    def __init__(self, rig: Any, out: Path, plan: CalibrationPlan, automatic: bool,
                 stop: threading.Event, send: Callable[[str, Any], None],
                 lost: Callable[[], str | None], open_rig: Callable[..., Any],
                 seed: int | None) -> None:
        self.rig, self.out, self.plan, self.automatic = rig, out, plan, automatic
        self.stop, self.send, self.lost = stop, send, lost
        self.open_rig, self.seed = open_rig, seed
        self._placed = threading.Event()
        self.prompt: str | None = None

    def placed(self) -> None:
        self._placed.set()

    def load(self, force: float, mass_kg: float, step: int, total: int) -> None:
        """The operator's loader: ask the window, wait for its answer or a stop."""
        self.prompt = weight_prompt(mass_kg, step, total, cell="load",
                                    where="on the load cell", confirm="press Weight placed")
        self._placed.clear()
        self.send("cell_prompt", {"step": step, "total": total, "text": self.prompt})
        while not self._placed.wait(0.05):
            if self.stop.is_set() or self.lost() is not None:
                raise RigError("calibration stopped by the operator")
        self.prompt = None

    def run(self) -> dict[str, Any]:
        """The whole calibration; the ``finished`` message's info."""
        from bench.engine.recorder import operator
        from bench.jobs.sensor_calibration import run_sensor_calibration, site_references

        gravity, acceptance = site_references(self.rig.calibration)
        with self.open_rig(self.rig, seed=self.seed) as rig:
            loader = sim_fixture(rig, self.plan.cell) if self.automatic else self
            if loader is None:
                raise RigError("automatic: this rig has no fixture the bench can drive; "
                               "place the weights by hand")
            outcome = run_sensor_calibration(
                self.rig, rig, self.plan, loader, gravity, self.out, acceptance=acceptance,
                meta={"operator": operator(), "command_line": ["rotorbench", "console"]})
        acc, fit = outcome.record["acceptance"], outcome.fit
        return {"kind": "cell calibration", "status": "success",
                "reason": ("calibration accepted" if acc["passed"] else
                           "calibration outside its acceptance limits: "
                           + "; ".join(acc["failed"])),
                "run_dir": str(outcome.run_dir), "trip": None,
                "rows": sum(p["samples"] for p in outcome.record["result"]["points"]),
                "t_end_s": 0.0, "gain": fit.scale, "u_gain": fit.u_scale(),
                "passed": acc["passed"], "failed": acc["failed"]}
