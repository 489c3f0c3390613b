"""The loop closed: one design's roll and pitch steps from three sources, side by side.

For one thesis-e design and the SizingLab catalogs' flight-time pick (4 actuators), with
the actuator measured on the simulated bench (``rotorbench step``, fitted by ``fly
--step-run``):

1. the thesis cascade's prediction (``fly --controller betaflight``'s ``cascade`` figures:
   the thesis' controller on the same plant and actuator);
2. Betaflight 4.6.0 in the loop on that plant (its ANGLE-mode roll and pitch steps, read on
   the plant's attitude);
3. Betaflight's own blackbox log of that flight (``rotorbench flight-report``: the rate
   loop's step response, H1, and the direct reading on the stick steps), and the motor
   time constants from the log's eRPM, synthesized from the plant, against the actuator.

Prints the Markdown table of docs/flight.md ("The loop closed"). Needs the ``sitl`` extra,
root and ``unshare`` (each flight runs in a network namespace of its own), about 40 s a
flight. Usage: ``python benchmarks/betaflight_loop_closed.py [--flights K]`` (K flights a
design: the spread under host load).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ROTORBENCH = Path(sys.executable).with_name("rotorbench")


def _f(x: float | None, spec: str = ".0f") -> str:
    return "-" if x is None else format(x, spec)


def run(*args: str, netns: bool = False) -> dict:
    cmd = [str(ROTORBENCH), *args, "--json"]
    if netns:
        cmd = ["unshare", "-n", "sh", "-c", 'ip link set lo up && exec "$0" "$@"', *cmd]
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False)
    if res.returncode != 0:
        sys.exit(f"{' '.join(cmd)}: exit {res.returncode}\n{res.stderr[-2000:]}")
    return json.loads(res.stdout)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--flights", type=int, default=1)
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="loop-closed-"))
    sl = str(tmp / "sizinglab")
    subprocess.run([str(ROTORBENCH), "import-sizinglab", "--source",
                    str(ROOT / "optimizer/data/sizinglab"), "--out", sl], check=True,
                   capture_output=True)
    pick = run("optimize", "--catalog", sl, "--actuators", "4", "--objective", "flight-time")
    best = pick["best"]
    designs = [("thesis-e", "optimizer/data/catalogs/thesis-e", ("P1", "M2", "B1")),
               ("SizingLab", sl, (best["propeller"], best["motor"], best["battery"]))]
    # the bench-measured actuator: a step run on the simulated rig
    bench = tmp / "bench"
    subprocess.run([str(ROTORBENCH), "step", "--repeats", "2", "--out", str(bench)],
                   check=True, capture_output=True)
    (step_run,) = sorted(p.parent for p in bench.glob("*-step1/run.json"))
    print("| design | maneuver | rise cascade (ms) | rise BF in the loop (ms) | rise BF log, "
          "rate loop (ms) | overshoot cascade (%) | overshoot BF in the loop (%) | "
          "overshoot BF log (%) |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    notes = []
    for cat_name, catalog, (p, m, b) in designs:
        for k in range(args.flights):
            out = run("fly", "--controller", "betaflight", "--catalog", catalog,
                      "--actuators", "4", "--propeller", p, "--motor", m, "--battery", b,
                      "--maneuver", "roll_step", "pitch_step", "--step-run", str(step_run),
                      "--store", str(tmp / "runs"), netns=True)
            log = out["log_step_response"]
            (tmp / f"{cat_name}-{k}.json").write_text(json.dumps(out, indent=1))
            for man, axis in (("roll_step", "x"), ("pitch_step", "y")):
                c, f, h = out["cascade"]["maneuvers"][man], out["maneuvers"][man], \
                    log[axis]["h1"]
                print(f"| {cat_name} {p}+{m}+{b} | {man} | {_f(c['rise_time_ms'])} | "
                      f"{_f(f['rise_time_ms'])} | {_f(h.get('rise_ms'))} "
                      f"(direct {_f(log[axis]['direct_rise_ms'])}) | "
                      f"{_f(c['overshoot_pct'], '.1f')} | {_f(f['overshoot_pct'], '.1f')} | "
                      f"{_f(h.get('overshoot_pct'), '.1f')} |", flush=True)
            a = out["actuator"]
            taus = [(r["tau_up_ms"], r["tau_down_ms"]) for r in out["log_motor_response"].values()]
            rt = out["betaflight"]["realtime"]
            notes.append(
                f"{cat_name} {p}+{m}+{b} flight {k + 1}: actuator tau up {a['tau_up_ms']:.1f} / "
                f"down {a['tau_down_ms']:.1f} ms, latency {a['latency_ms']:.1f} ms "
                f"({a['source']}); from the log's eRPM: up "
                f"{min(u for u, _ in taus):.1f}-{max(u for u, _ in taus):.1f}, down "
                f"{min(d for _, d in taus):.1f}-{max(d for _, d in taus):.1f} ms; real-time "
                f"factor {rt['real_time_factor']:.3f}, longest wait "
                f"{1e3 * rt['longest_wait_s']:.0f} ms")
    print(f"\n(flights' JSON in {tmp})")
    for n in notes:
        print(f"- {n}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
