"""The static command -> thrust map, fitted from a slow sweep (Paper C section 4.4).

The thesis found its static functions "by increasing the RPM slowly to reduce the
significance of the system dynamics" and fitting polynomials to the logged data. Here the
rising ramp of a sweep run is averaged in command bins, a polynomial in the command is
fitted to the spinning part, and the map is stored as a monotonic table
(``command_us``, ``thrust_n``) with the rig; thrust steps invert it by interpolation.
The same run also gives thrust and current against speed (Fig. C.13 and C.14), stored
as polynomial coefficients in the run folder (``static_map.json``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.polynomial import Polynomial

from bench.engine.recorder import atomic_write_json
from bench.errors import RigError, ThrustOutsideMap

if TYPE_CHECKING:  # pandas is imported where a sweep is fitted: a step run needs only the map
    import pandas as pd

__all__ = ["StaticThrustMap", "SweepFit", "fit_sweep", "fit_sweep_run"]

RPM_TO_RAD_S = 2.0 * np.pi / 60.0


@dataclass(frozen=True)
class StaticThrustMap:
    """A monotonic table from ESC command (us) to steady thrust (N)."""

    command_us: np.ndarray
    thrust_n: np.ndarray
    source: str = ""

    def __post_init__(self) -> None:
        c = np.asarray(self.command_us, float)
        f = np.asarray(self.thrust_n, float)
        where = self.source or "thrust map"
        if c.ndim != 1 or c.shape != f.shape or c.size < 2:
            raise RigError(f"{where}: command_us and thrust_n must be 1-D and of equal length "
                           f">= 2 (got {c.shape} and {f.shape})")
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(f))):
            raise RigError(f"{where}: command_us and thrust_n must be finite numbers")
        if np.any(np.diff(c) <= 0) or np.any(np.diff(f) <= 0):
            raise RigError(f"{where}: command_us and thrust_n must both increase strictly")
        object.__setattr__(self, "command_us", c)
        object.__setattr__(self, "thrust_n", f)

    @classmethod
    def from_rig(cls, thrust_map: Any, source: str = "") -> StaticThrustMap | None:
        """From the rig's ``thrust_map`` (an object with ``command_us``/``thrust_n``, a
        mapping with those keys, or None)."""
        if thrust_map is None:
            return None
        if isinstance(thrust_map, StaticThrustMap):
            return thrust_map
        get = thrust_map.get if isinstance(thrust_map, dict) else \
            lambda k: getattr(thrust_map, k, None)
        return cls(np.asarray(get("command_us"), float), np.asarray(get("thrust_n"), float),
                   source)

    def command_for(self, thrust_n: float) -> float:
        """The command that gives ``thrust_n`` in steady state (inverse by interpolation)."""
        lo, hi = self.thrust_n[0], self.thrust_n[-1]
        if not lo <= thrust_n <= hi:
            raise ThrustOutsideMap(f"{self.source or 'thrust map'}: setpoint {thrust_n:.3f} N "
                                   f"outside the measured range {lo:.3f}-{hi:.3f} N; sweep a "
                                   "wider range", float(lo), float(hi))
        return float(np.interp(thrust_n, self.thrust_n, self.command_us))

    def thrust_at(self, command_us: float | np.ndarray) -> np.ndarray | float:
        return np.interp(command_us, self.command_us, self.thrust_n)


@dataclass(frozen=True)
class SweepFit:
    """What a sweep run gives: the thrust map and the Fig. C.13/C.14 polynomials."""

    thrust_map: StaticThrustMap
    thrust_poly_us: Polynomial  # thrust (N) against command (us)
    thrust_poly_w: Polynomial  # thrust (N) against speed (rad/s), Fig. C.13
    current_poly_w: Polynomial  # current (A) against speed (rad/s), Fig. C.14
    residual_rms_n: float
    bins: pd.DataFrame

    def to_dict(self) -> dict[str, Any]:
        def poly(p: Polynomial) -> dict[str, Any]:
            return {"coef_power_series": p.convert().coef.tolist(), "domain": p.domain.tolist()}

        return {
            "command_us": self.thrust_map.command_us.tolist(),
            "thrust_n": self.thrust_map.thrust_n.tolist(),
            "thrust_vs_command_us": poly(self.thrust_poly_us),
            "thrust_vs_speed_rad_s": poly(self.thrust_poly_w),
            "current_vs_speed_rad_s": poly(self.current_poly_w),
            "residual_rms_n": self.residual_rms_n,
        }


def fit_sweep(samples: pd.DataFrame, bin_us: float = 5.0, degree: int = 3,
              min_thrust_n: float = 0.05, step_us: float = 5.0, source: str = "sweep") -> SweepFit:
    """Fit the static maps from the rising-ramp rows of a sweep (``t_s``, ``throttle_us``,
    ``thrust_n``, ``current_a``, ``rpm``). Rows should already be limited to the ramp."""
    import pandas as pd
    need = ("throttle_us", "thrust_n", "current_a", "rpm")
    missing = [c for c in need if c not in samples]
    if missing:
        raise RigError(f"{source}: samples lack the columns {missing}")
    df = samples.loc[:, list(need)].dropna()
    if len(df) < 10:
        raise RigError(f"{source}: too few samples on the rising ramp to fit a map")
    edges = np.arange(df["throttle_us"].min(), df["throttle_us"].max() + bin_us, bin_us)
    groups = df.groupby(pd.cut(df["throttle_us"], edges, include_lowest=True), observed=True)
    bins = groups.mean().dropna()
    spinning = bins[bins["thrust_n"] > min_thrust_n]
    if len(spinning) < degree + 2:
        raise RigError(f"{source}: the ramp gave thrust above {min_thrust_n} N in only "
                       f"{len(spinning)} command bins; sweep a wider range")
    us = spinning["throttle_us"].to_numpy()
    f = spinning["thrust_n"].to_numpy()
    w = spinning["rpm"].to_numpy() * RPM_TO_RAD_S
    p_us = Polynomial.fit(us, f, degree)
    residual = float(np.sqrt(np.mean((p_us(us) - f) ** 2)))
    p_w = Polynomial.fit(w, f, 2)
    p_i = Polynomial.fit(w, spinning["current_a"].to_numpy(), 2)
    grid = np.arange(us[0], us[-1] + 0.5 * step_us, step_us)
    thrust = p_us(grid)
    keep = (thrust > min_thrust_n) & (thrust > np.maximum.accumulate(
        np.concatenate([[-np.inf], thrust[:-1]])))
    if np.count_nonzero(keep) < 2:
        raise RigError(f"{source}: the fitted thrust does not rise with the command")
    tm = StaticThrustMap(grid[keep], thrust[keep], source)
    return SweepFit(tm, p_us, p_w, p_i, residual, spinning)


def fit_sweep_run(run_dir: Path) -> SweepFit:
    """Fit a recorded sweep run: uses its longest rising ramp; writes ``static_map.json``."""
    run_dir = Path(run_dir)
    meta_path = run_dir / "run.json"
    try:
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:  # ValueError: not UTF-8, not JSON
        raise RigError(f"{meta_path}: cannot read the run record ({exc})") from None
    segments = meta.get("plan", {}).get("segments", [])
    ramps = [s for s in segments if s.get("kind") == "ramp" and s["us_end"] > s["us_start"]]
    if not ramps:
        raise RigError(f"{meta_path}: plan.segments has no rising ramp; is this a sweep run?")
    ramp = max(ramps, key=lambda s: s["duration_s"])
    import pandas as pd

    from analysis.errors import LogError
    from analysis.run_paths import samples_path

    try:
        samples = pd.read_parquet(samples_path(run_dir, meta))
    except LogError as exc:
        raise RigError(str(exc)) from None
    rows = samples.loc[samples["step"] == ramp["index"]]
    fit = fit_sweep(rows, source=str(run_dir))
    atomic_write_json(run_dir / "static_map.json", fit.to_dict())
    return fit
