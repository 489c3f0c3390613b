"""A whole IMU calibration on the bench: every Paper A stage as its own recorded run.

``run_calibration`` opens the IMU bench once (the IMU keeps its clock across stages, as on
a real bench), runs each stage's plan through the one recording path
(:func:`bench.plan_runner.session.run_stage`: the runner of :mod:`bench.plan_runner.runner`)
into its own run folder (indexed in ``runs.sqlite`` like every other run), stops at the
first stage that does not succeed, and closes the devices (hexapod stopped) whatever
happened. ``collect_log`` joins the stages' samples on the rig clock into one calibration
log in the format of :mod:`analysis.imu_log`, which :mod:`analysis.imu_calibration` reads.
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from analysis.imu_calibration import Calibration, calibrate
from bench.engine import run_log
from bench.errors import RigError
from bench.plan_runner.runner import HexapodRunOptions
from bench.plan_runner.session import RunOutcome, run_stage
from bench.plans.calibration_sequences import (
    HexapodSegment,
    compile_plan,
    paper_a_sequences,
)
from bench.plans.sequences import Plan
from bench.plans.sequences import Sequence as PlanSequence
from drivers.contracts import Trajectory

__all__ = ["CalibrationRun", "calibrate_frame", "collect_log", "plans_for", "preflight",
           "run_calibration"]


@dataclass
class CalibrationRun:
    """The stages run so far; ``complete`` when every stage succeeded."""

    stages: list[RunOutcome] = field(default_factory=list)
    planned: int = 0
    truth: dict[str, Any] | None = None

    @property
    def complete(self) -> bool:
        return (len(self.stages) == self.planned
                and all(s.result.status == "success" for s in self.stages))


def plans_for(rig: Any, sequences: Sequence[PlanSequence]) -> list[Plan]:
    """Compile every stage against the rig's hexapod limits and pivot (no device touched)."""
    limits = rig.hexapod.hexapod_limits()
    return [compile_plan(s, limits, tuple(rig.hexapod.pivot_m)) for s in sequences]


def preflight(bench: Any, plans: Sequence[Plan], rate_hz: float) -> None:
    """Every motion of every stage against what the controller itself reports (travel
    limits, referenced, servo), before anything moves; a hexapod that cannot tell
    (no ``check_motion``) is checked against the rig file's limits only."""
    check = getattr(bench.hexapod, "check_motion", None)
    if check is None:
        return
    for plan in plans:
        for seg in plan.segments:
            if seg.motion is not None:  # a Move step's segment
                check(Trajectory.from_motion(seg.motion, rate_hz))


def run_calibration(rig: Any, out_root: Path, *, quick: bool = False, seed: int | None = None,
                    options: HexapodRunOptions | None = None,
                    sequences: Sequence[PlanSequence] | None = None,
                    on_stage: Callable[[int, Plan], None] | None = None,
                    on_progress: Callable[[float, float, HexapodSegment], None] | None = None,
                    stop_event: threading.Event | None = None,
                    open_bench: Callable[..., Any] | None = None,
                    extra_meta: Mapping[str, Any] | None = None) -> CalibrationRun:
    """Run every stage (Paper A by default) on the rig; see module docstring."""
    if open_bench is None:
        from drivers.factory import open_rig as open_bench
    rate = rig.imu.value("rate_hz")
    seqs = list(sequences) if sequences is not None else paper_a_sequences(rate, quick)
    plans = plans_for(rig, seqs)  # every stage checked before anything moves
    out = CalibrationRun(planned=len(plans))
    with run_log.capture():  # the bring-up goes into the first stage's run.log
        bench = open_bench(rig, seed=seed)
        try:
            preflight(bench, plans, (options.trajectory_rate_hz if options is not None
                                     else rig.hexapod.trajectory_rate_hz))
            sim = getattr(bench, "sim", None)
            if sim is not None:
                truth = sim.truth()
                pivot = np.asarray(rig.hexapod.pivot_m, float)
                # R as the calibration sees it: from the pivot
                truth["pivot_m"] = pivot.tolist()
                truth["lever_arm_from_pivot_m"] = (np.asarray(truth["lever_arm_m"])
                                                   + np.asarray(truth["cg_m"]) - pivot).tolist()
                out.truth = truth
            meta = {**dict(extra_meta or {}),
                    **({"sim_truth": out.truth} if out.truth is not None else {})}
            for i, plan in enumerate(plans):
                if on_stage is not None:
                    on_stage(i, plan)
                stage = run_stage(bench, rig, plan, out_root, options=options,
                                  on_progress=on_progress, stop_event=stop_event,
                                  extra_meta={**meta, "stage": i + 1, "stages": len(plans)})
                out.stages.append(stage)
                if stage.result.status != "success":
                    break
        finally:
            bench.close()
    return out


def collect_log(run_dirs: Sequence[Path], path: Path) -> Path:
    """Join the stages' samples on the rig clock into one calibration log (atomic write).

    Each run's ``t_s`` is relative to its start; adding the run's ``rig_t0_s`` (run.json)
    puts all stages on the one continuous clock of the bench.
    """
    from analysis.imu_log import write_table
    from analysis.run_paths import read_run_json, samples_path

    frames = []
    for run_dir in run_dirs:
        run_dir = Path(run_dir)
        try:
            meta = read_run_json(run_dir)
            df = pd.read_parquet(samples_path(run_dir, meta))
        except (OSError, ValueError) as exc:  # LogError: a ValueError naming the file
            raise RigError(f"{run_dir}: cannot read the run's samples: {exc}") from None
        if "rig_t0_s" not in meta:
            raise RigError(f"{run_dir}/run.json: field rig_t0_s: missing (not a hexapod run?)")
        df = df.sort_values("t_s", kind="stable")
        df["t_s"] = df["t_s"].to_numpy(float) + float(meta["rig_t0_s"])
        df["phase"] = df["phase"].astype(str)
        frames.append(df.drop(columns=["step"], errors="ignore"))
    if not frames:
        raise RigError("no stage runs to collect")
    log = pd.concat(frames, ignore_index=True)
    return write_table(log, path)


def calibrate_frame(df: pd.DataFrame, mounting: tuple[float, float, float] | None,
                    gyro_range_rad_s: float, acc_range_m_s2: float,
                    max_lag_s: float) -> Calibration:
    """Paper A's stages on a validated log; warnings are kept in ``cal.warnings`` (the CLI
    and the console print or store them with the result, not as Python warnings)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return calibrate(df, measured_mounting_deg=mounting, gyro_range_rad_s=gyro_range_rad_s,
                         acc_range_m_s2=acc_range_m_s2, max_lag_s=max_lag_s)
