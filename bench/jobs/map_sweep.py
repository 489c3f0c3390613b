"""Measure a rig's static thrust map: run the slow sweep, fit it, store it with the rig.

``rotorbench sweep`` does this, and so does ``rotorbench step`` when its rig has no map
yet (thrust setpoints need one, Paper C section 4.4); both call :func:`measure_map`.
A shipped or read-only rig is never rewritten: the rig is copied under ``<out>/rigs/``
with the map beside it.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from bench.jobs.run_progress import JobOutput, report, run_with_progress
from bench.plan_runner.runner import RunOptions
from bench.plans.plan_specs import sweep_sequence
from bench.plans.thrust_map import fit_sweep_run
from bench.rig.rig import is_shipped_rig, map_goes_to_copy, rig_copy_path, save_thrust_map

__all__ = ["measure_map"]


def measure_map(rig: Any, out: Path, *, start_us: float = 1100.0, end_us: float = 1900.0,
                duration_s: float = 20.0, limits: Mapping[str, float] | None = None,
                save: bool = True, seed: int | None = None,
                options: RunOptions | None = None, live: bool = False,
                confirmed: bool = False, output: JobOutput) -> tuple[Any, int]:
    """Run a sweep, fit the map, store it with the rig, saying so through ``output``;
    returns (rig, exit code)."""
    seq = sweep_sequence(start_us, end_us, duration_s, limits)
    outcome = run_with_progress(rig, seq, out, seed=seed, options=options, live=live,
                                confirmed=confirmed, output=output)
    code = report(outcome, output)
    if code:
        return rig, code
    fit = fit_sweep_run(outcome.run_dir)
    tm = fit.thrust_map
    output.out(f"static thrust map: {tm.command_us[0]:.0f}-{tm.command_us[-1]:.0f} us -> "
               f"{tm.thrust_n[0]:.3f}-{tm.thrust_n[-1]:.3f} N, fit residual "
               f"{fit.residual_rms_n * 1000:.1f} mN rms ({outcome.run_dir / 'static_map.json'})")
    if save and map_goes_to_copy(rig):  # shipped/read-only rig: store a copy with the map
        original = rig.path
        why = "a shipped rig" if is_shipped_rig(original) else "not writable"
        dest = rig_copy_path(original, out).parent
        rig = save_thrust_map(rig, tm.command_us.tolist(), tm.thrust_n.tolist(), dest_dir=dest)
        output.out(f"{original} is {why}, left unchanged: the rig with the new map is "
                   f"{rig.path} (map {rig.thrust_map_path.name} beside it); `--rig "
                   f"{rig.path}` uses it, as do step and sweep with --out {out}")
    elif save:
        rig = save_thrust_map(rig, tm.command_us.tolist(), tm.thrust_n.tolist())
        output.out(f"stored with the rig: {rig.thrust_map_path}")
    return rig, 0
