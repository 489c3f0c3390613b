"""paper-b's two time constants: blend τ (P = t_s/τ) and earth-frame low-pass τ_lp.

Inclination RMSE (deg, BROAD scoring over the movement samples) of
:func:`analysis.attitude_filters.paper_b` for a few (τ, τ_lp) pairs on BROAD trial 07, its
BROAD-shaped variants (``drivers.sim.imu_disturbances``, seed 0) and the simulated
recordings of ``benchmarks/attitude_bench.py`` (hexapod, tumble, tour), next to VQF (the
better of online and offline 6D) and the bound ``paper-b`` is held to, 2 x VQF + 0.5°. τ = 3 s with
τ_lp = 0 is the printed correction's gain with the correction taken on the earth side.
Prints a Markdown table (docs/attitude.md holds its output).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from analysis.attitude_filters import paper_b, run_filter
from analysis.attitude_scoring import score
from analysis.imu_recording import ImuRecording, read_broad
from drivers.sim.imu_attitude_log import simulate_attitude_log
from drivers.sim.imu_disturbances import VARIANTS, make_variant
from drivers.sim.imu_tumble import simulate_orientation_tour, simulate_tumble

REPO = Path(__file__).resolve().parents[1]
BROAD = REPO / "fixtures" / "data" / "broad" / "07_undisturbed_fast_rotation_B.hdf5"
PAIRS = ((3.0, 0.0), (3.0, 1.0), (3.0, 3.0), (2.0, 1.0), (1.5, 1.5), (1.0, 2.0))


def _rec(name: str, d: dict) -> ImuRecording:
    return ImuRecording(name, d["t_s"], d["gyro"], d["acc"], d.get("mag"), d["quat"],
                        d.get("movement"))


def _cases() -> list[ImuRecording]:
    out = []
    if BROAD.exists():
        r = read_broad(BROAD)
        trial = {"t_s": r.t_s, "gyro": r.gyro_rad_s, "acc": r.acc_m_s2, "mag": r.mag_ut,
                 "quat": r.ref_quat, "movement": r.movement}
        out.append(_rec("trial 07", trial))
        out += [_rec(n, make_variant(trial, n, 0)) for n in VARIANTS]
    else:
        print(f"BROAD trial not found at {BROAD}; simulated data only", file=sys.stderr)
    c = simulate_attitude_log(seed=0)
    out.append(ImuRecording(
        "hexapod (sim)", c["t_s"], np.stack([c[f"gyro_{a}_rad_s"] for a in "xyz"], axis=1),
        np.stack([c[f"acc_{a}_m_s2"] for a in "xyz"], axis=1), None,
        np.stack([c[k] for k in ("ref_qw", "ref_qx", "ref_qy", "ref_qz")], axis=1)))
    out.append(_rec("tumble (sim)", simulate_tumble(duration_s=60.0, seed=0)))
    out.append(_rec("tour (sim)", simulate_orientation_tour(seed=0)))
    return out


def _incl(q: np.ndarray, rec: ImuRecording) -> float:
    s = score(q, rec.ref_quat, rec.movement, remove_heading_offset=True)
    return math.degrees(s.inclination_rad)


def main() -> int:
    heads = [f"τ {a:g} s, τ_lp {b:g} s" for a, b in PAIRS]
    print("| data | VQF 6D | bound | paper-b-printed | " + " | ".join(heads) + " |")
    print("|" + " --- |" * (4 + len(PAIRS)))
    for rec in _cases():
        vqf = min(_incl(run_filter(n, rec).quat, rec) for n in ("vqf-6d", "vqf-offline-6d"))
        printed = _incl(run_filter("paper-b-printed", rec).quat, rec)
        cells = [f"{_incl(paper_b(rec, tau_s=a, earth_lowpass_s=b), rec):.2f}" for a, b in PAIRS]
        print(f"| {rec.source} | {vqf:.2f} | {2 * vqf + 0.5:.2f} | {printed:.2f} | "
              + " | ".join(cells) + " |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
