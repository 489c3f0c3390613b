"""The IMU calibration as tables on the terminal, in the shape of Paper A's.

``rotorbench calibrate`` prints these for a log (``--from-log``) and for a calibration on
the rig (the stages run, and on a simulated rig the estimates against the simulator's
hidden truth); the tables are built here, each handed to ``show`` (the command's
``Console.print``), so the command stays a thin argument parser.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from rich.table import Table

from analysis.imu_calibration import Calibration

__all__ = ["mat", "show_calibration", "show_stages", "show_truth", "vec"]

_XYZ = ("x", "y", "z")


def vec(v, fmt: str) -> str:
    return "[" + ", ".join(fmt.format(float(x)) for x in v) + "]"


def mat(k) -> str:
    return "\n".join(vec(row, "{:+.4f}") for row in np.asarray(k))


def show_calibration(cal: Calibration, show: Callable[..., None]) -> None:
    s = Table(title="IMU calibration (Paper A)")
    s.add_column("quantity")
    s.add_column("value")
    bias = ", ".join(f"{b:+.5f} ± {e:.5f}" for b, e in
                     zip(cal.gyro_bias_rad_s, cal.gyro_bias_stderr_rad_s, strict=True))
    s.add_row("gyro bias (A.12), rad/s", bias)
    s.add_row("accelerometer bias, m/s²", vec(cal.acc_bias_m_s2, "{:+.4f}"))
    s.add_row("time offset hexapod→IMU", f"{cal.time_offset_s * 1e3:.2f} ms")
    s.add_row(f"K_ω (A.13), cond {cal.conditioning.get('gyro', float('nan')):.2f}",
              mat(cal.k_gyro))
    s.add_row(f"K_a (A.14), cond {cal.conditioning.get('acc', float('nan')):.2f}",
              mat(cal.k_acc))
    s.add_row("lever arm R, m", vec(cal.lever_arm_m, "{:+.4f}"))
    show(s)

    d = Table(title="K split into rotation, scale, non-orthogonality (A.15-A.16)",
              caption=cal.decomposition.get("convention", ""))
    for col in ("sensor", "φ, θ, ψ (deg)", "scale", "non-orth xy, xz, yz (deg)",
                "vs measured (deg)"):
        d.add_column(col)
    for name in ("gyro", "acc"):
        p = cal.decomposition.get(name, {})
        if not p:
            continue
        vs = p.get("rotation_vs_measured_deg")
        d.add_row(name, vec(p["euler_deg"], "{:.3f}"), vec(p["scale"], "{:.4f}"),
                  vec(p["nonorthogonality_deg"], "{:+.3f}"), "-" if vs is None else f"{vs:.3f}")
    show(d)

    est = cal.lever_arm_estimates
    la = Table(title="Lever arm estimates from α (A.11), m (Table A.1 layout)")
    for col in ("rotation axis", "R_x", "R_y", "R_z"):
        la.add_column(col)
    for ax in _XYZ:
        row = est.get("table_a1_alpha_m", {}).get(ax, {})
        la.add_row(f"ω_{ax}", *(f"{row[c]:+.4f}" if c in row else "-" for c in _XYZ))
    la.add_row("final (mean)", *(f"{v:+.4f}" for v in cal.lever_arm_m))
    la.add_row("agreement |Δ|", *(f"{v * 1e3:.2f} mm" for v in est.get("agreement_m", [])))
    for ax in _XYZ:
        row = est.get("omega2_m", {}).get(ax, {})
        la.add_row(f"ω_{ax} (ω² term)", *(f"{row[c]:+.3f}" if c in row else "-" for c in _XYZ))
    show(la)

    v = cal.verification_rms
    if v is None:
        show("no 'verify' phase in the log: verification RMS not computed")
    else:
        t = Table(title=f"Verification RMS (A.19) on the independent motion, "
                        f"{v['samples']} samples (Table A.2)")
        for col in ("signal", "raw", "corrected", "% of range", "% of peak", "Table A.2"):
            t.add_column(col)
        for kind, unit, pk in (("acc_m_s2", "m/s²", "acc_pct_peak"),
                               ("gyro_rad_s", "rad/s", "gyro_pct_peak")):
            short = "a" if kind.startswith("acc") else "ω"
            pct = v["acc_pct_range" if short == "a" else "gyro_pct_range"]["corrected"]
            for i, ax in enumerate(_XYZ):
                t.add_row(f"{short}_{ax} ({unit})", f"{v[kind]['raw'][i]:.4f}",
                          f"{v[kind]['corrected'][i]:.4f}", f"{pct[i]:.3f} %",
                          f"{v[pk][i]:.2f} %", f"{v['table_a2'][kind][i]:.4f}")
        show(t)
    for w in cal.warnings:
        show(f"[yellow]warning:[/yellow] {w}")


def show_stages(run: Any, show: Callable[..., None]) -> None:
    t = Table(title="calibration stages (one recorded run each)")
    for col in ("stage", "status", "rows", "rig time (s)", "run folder"):
        t.add_column(col)
    for s in run.stages:
        r = s.result
        t.add_row(s.plan.sequence.name, f"{r.status}: {r.reason}", str(r.rows),
                  f"{r.t_end_s:.1f}", str(s.run_dir))
    show(t)


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def show_truth(cal: Calibration, truth: dict, show: Callable[..., None]) -> None:
    """The estimates against the simulator's hidden truth (simulated rigs only)."""
    t = Table(title="against the simulated IMU's truth")
    for col in ("quantity", "estimated", "true", "error"):
        t.add_column(col)
    t.add_row("K_ω", "", "", f"{100 * _rel(cal.k_gyro, truth['k_gyro']):.3f} % (rel. Frobenius)")
    t.add_row("K_a", "", "", f"{100 * _rel(cal.k_acc, truth['k_acc']):.3f} % (rel. Frobenius)")
    r_true = np.asarray(truth["lever_arm_from_pivot_m"])
    err = (np.asarray(cal.lever_arm_m) - r_true) * 1e3
    t.add_row("lever arm R (m)", vec(cal.lever_arm_m, "{:+.4f}"), vec(r_true, "{:+.4f}"),
              vec(err, "{:+.2f}") + " mm")
    z = (np.asarray(cal.gyro_bias_rad_s) - truth["gyro_bias_rad_s"]) / \
        np.asarray(cal.gyro_bias_stderr_rad_s)
    t.add_row("gyro bias (rad/s)", vec(cal.gyro_bias_rad_s, "{:+.5f}"),
              vec(truth["gyro_bias_rad_s"], "{:+.5f}"), vec(z, "{:+.2f}") + " std. err.")
    t.add_row("time offset (ms)", f"{cal.time_offset_s * 1e3:.2f}",
              f"{truth['clock_offset_s'] * 1e3:.2f}",
              f"{(cal.time_offset_s - truth['clock_offset_s']) * 1e3:+.2f} ms")
    psi = cal.decomposition.get("gyro", {}).get("euler_deg", [math.nan] * 3)
    t.add_row("mounting φ, θ, ψ (deg, from K_ω)", vec(psi, "{:.3f}"),
              vec(truth["mounting_deg"], "{:.3f}"), "")
    show(t)
