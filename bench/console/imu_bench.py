"""The console's IMU-bench runs: a Paper A calibration on an IMU rig, started from the IMU tab.

Each stage is recorded and indexed by :func:`bench.jobs.calibration_stages.run_calibration` (the
HexapodRunner: limits, watchdog, hexapod stopped in a ``finally``), exactly as
``rotorbench calibrate --rig`` does; the console adds only its stop and its liveness check
(a lost window sets the stop event, which ends the stage at its next tick with the hexapod
stopped) and, once every stage succeeded, the calibration (``collect_log`` +
``calibrate_frame``) written next to the runs.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = ["ImuCalibration", "commanded_pose", "imu_rig_info"]


def commanded_pose(seg: Any, t_s: float) -> list[float]:
    """The pose (x, y, z m, roll, pitch, yaw rad) the segment's motion commands at plan
    time ``t_s``; the home pose outside a motion (holds, pivot changes)."""
    motion = getattr(seg, "motion", None)
    if motion is None:
        return [0.0] * 6
    pose, _, _ = motion.evaluate(t_s - seg.t_start_s)
    return [float(v) for v in pose[0]]


def imu_rig_info(rig: Any) -> dict[str, Any]:
    """What the window needs to know of an IMU rig (no ESC, no propulsion limits)."""
    return {"devices": {r: d.url for r, d in rig.devices.items()},
            "esc": {"idle_us": 1000.0, "min_us": 1000.0, "max_us": 2000.0},
            "rig_limits": {}, "hexapod_limits": dict(rig.hexapod.limits),
            "thrust_cap_us": None}


class ImuCalibration:
    """One calibration on a worker thread; :meth:`snapshot` is what the IMU tab shows."""

    def __init__(self, rig: Any, out: Path, quick: bool, stop: threading.Event,
                 lost: Callable[[], str | None]) -> None:
        self.rig, self.out, self.quick = rig, Path(out), quick
        self.stop, self.lost = stop, lost
        self.progress: dict[str, Any] = {"stage": 0, "stages": 0, "name": "", "phase": "",
                                         "label": "", "t": 0.0, "total": 0.0}
        self.lost_reason: str | None = None

    def _on_stage(self, i: int, plan: Any) -> None:
        self.progress.update(stage=i + 1, name=plan.sequence.name, t=0.0,
                             total=plan.duration_s)

    def _on_progress(self, t: float, total: float, seg: Any) -> None:
        """Every tick: the progress and the liveness check. Peaks and pose wait for
        :meth:`snapshot`: the window is sent them ten times a second, while an unpaced
        simulated stage ticks some 200 times a second (evaluating the motion on each
        tick was 7 % of a stage's CPU time)."""
        # one update, as before: a snapshot taken meanwhile sees the tick whole
        self.progress.update(t=t, total=total, phase=seg.phase, label=seg.label, at=(seg, t))
        lost = self.lost()
        if lost is not None and not self.stop.is_set():
            self.lost_reason = lost
            self.stop.set()  # the stage ends at its next tick, hexapod stopped

    def snapshot(self) -> dict[str, Any]:
        """The progress as the window shows it, with the newest tick's motion peaks and
        commanded pose (what ``progress`` held after that tick before)."""
        out = dict(self.progress)
        at = out.pop("at", None)
        if at is not None:
            seg, t = at
            out.update(peaks={k: round(float(v), 4) for k, v in seg.peaks.items()},
                       pose=commanded_pose(seg, t))
        return out

    def run(self) -> dict[str, Any]:
        from analysis.imu_log import load_calibration_log
        from bench.engine.recorder import new_run_id
        from bench.jobs.calibration_stages import (
            calibrate_frame,
            collect_log,
            plans_for,
            run_calibration,
        )
        from bench.plan_runner.runner import HexapodRunOptions
        from bench.plans.calibration_sequences import paper_a_sequences

        rig = self.rig
        seqs = paper_a_sequences(rig.imu.value("rate_hz"), quick=self.quick)
        plans = plans_for(rig, seqs)
        self.progress["stages"] = len(plans)
        session = new_run_id("calibration")
        options = HexapodRunOptions(realtime=not rig.is_simulated,
                                    trajectory_rate_hz=rig.hexapod.trajectory_rate_hz)
        run = run_calibration(rig, self.out, quick=self.quick, options=options,
                              sequences=seqs, on_stage=self._on_stage,
                              on_progress=self._on_progress, stop_event=self.stop,
                              extra_meta={"command_line": ["rotorbench", "console"],
                                          "calibration_session": session,
                                          "quick": self.quick})
        last = run.stages[-1] if run.stages else None
        info: dict[str, Any] = {
            "kind": "calibration", "status": "success" if run.complete else
            (last.result.status if last else "fail"),
            "reason": f"{len(run.stages)}/{run.planned} stages" + (
                f"; {last.result.reason}" if last and not run.complete else ""),
            "run_dir": str(last.run_dir) if last else "", "trip": None,
            "rows": sum(s.result.rows for s in run.stages),
            "t_end_s": sum(s.result.t_end_s for s in run.stages),
            "stages": [{"name": s.plan.sequence.name, "status": s.result.status,
                        "run_dir": str(s.run_dir)} for s in run.stages]}
        if self.lost_reason:
            info["reason"] += f" (stopped: {self.lost_reason}; hexapod stopped)"
        if run.complete:
            log_path = collect_log([s.run_dir for s in run.stages],
                                   self.out / f"{session}.parquet")
            df = load_calibration_log(log_path)
            cal = calibrate_frame(df, rig.imu.measured_mounting_deg,
                                  rig.imu.value("gyro_range_rad_s"),
                                  rig.imu.value("acc_range_m_s2"), max_lag_s=0.5)
            cal.source = str(log_path)
            path = self.out / f"{session}.json"
            path.write_text(json.dumps(cal.to_dict(), indent=2, default=float) + "\n",
                            encoding="utf-8")
            info["calibration"] = str(path)
        return info
