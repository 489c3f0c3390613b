"""The loop closed: one design's roll and pitch steps from three sources, side by side.

For one thesis-e design and the SizingLab catalogs' flight-time pick (4 actuators), with
the actuator measured on the simulated bench (``rotorbench step``, fitted by ``fly
--step-run``):

1. angle steps (ANGLE mode, 10 deg): the thesis cascade's prediction (``fly --controller
   betaflight``'s ``cascade`` figures: the thesis' controller on the same plant and
   actuator) beside Betaflight 4.6.0 in the loop, both read on the plant's attitude;
2. rate steps (acro, +-100 deg/s): Betaflight in the loop read on the plant's body rate,
   and its own blackbox log of that flight (``rotorbench flight-report``: the gyro read
   directly on the steps, and the rate loop's deconvolved step response, H1): one loop
   three ways, like with like;
3. how far H1's rise is from the direct median, flight by flight, and the motor time
   constants from the log's eRPM, synthesized from the plant, against the actuator.

Prints the Markdown tables of docs/flight.md ("The loop closed"). Needs the ``sitl`` extra,
root and ``unshare`` (each flight runs in a network namespace of its own), about 30 s a
flight; a flight that fails (the host's load) is flown again, up to 3 times. Usage:
``python benchmarks/betaflight_loop_closed.py [--flights K]`` (K flights a design: the
spread under host load); ``--reread DIR`` prints the tables again from the flights' JSON
in DIR, their stored logs read again by the current code.
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


def _span(xs: list, spec: str = ".0f") -> str:
    """A figure over the flights: its range (one flight: its value)."""
    got = [x for x in xs if x is not None]
    if not got:
        return "-"
    lo, hi = min(got), max(got)
    return _f(lo, spec) if format(lo, spec) == format(hi, spec) else \
        f"{_f(lo, spec)}-{_f(hi, spec)}"


def run(*args: str, netns: bool = False) -> dict:
    cmd = [str(ROTORBENCH), *args, "--json"]
    if netns:
        cmd = ["unshare", "-n", "sh", "-c", 'ip link set lo up && exec "$0" "$@"', *cmd]
    tries = 3 if netns else 1  # a flight may fail for the host's load alone
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False)
    while res.returncode != 0 and (tries := tries - 1) > 0:
        print(f"(retrying: {res.stderr.strip().splitlines()[-1:]})", file=sys.stderr)
        res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False)
    if res.returncode != 0:
        sys.exit(f"{' '.join(cmd)}: exit {res.returncode}\n{res.stderr[-2000:]}")
    return json.loads(res.stdout)


def main() -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--flights", type=int, default=1)
    ap.add_argument("--reread", type=Path, metavar="DIR",
                    help="print the tables again from a run's folder (its flights' JSON), "
                         "the stored logs read again by this code")
    args = ap.parse_args()
    if args.reread is not None:
        return _reread(args.reread)
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
    flights: dict[str, list[dict]] = {}
    notes = []
    for cat_name, catalog, (p, m, b) in designs:
        label = f"{cat_name} {p}+{m}+{b}"
        for k in range(args.flights):
            out = run("fly", "--controller", "betaflight", "--catalog", catalog,
                      "--actuators", "4", "--propeller", p, "--motor", m, "--battery", b,
                      "--maneuver", "roll_step", "pitch_step", "--step-run", str(step_run),
                      "--store", str(tmp / "runs"), netns=True)
            (tmp / f"{cat_name}-{k}.json").write_text(json.dumps(out, indent=1))
            flights.setdefault(label, []).append(out)
            a = out["actuator"]
            taus = [(r["tau_up_ms"], r["tau_down_ms"]) for r in out["log_motor_response"].values()]
            rt = out["betaflight"]["realtime"]
            notes.append(
                f"{label} flight {k + 1}: PIDs x "
                f"{out['betaflight']['simplified_master_multiplier']} %; actuator tau up "
                f"{a['tau_up_ms']:.1f} / down {a['tau_down_ms']:.1f} ms, latency "
                f"{a['latency_ms']:.1f} ms; from the log's eRPM: up "
                f"{min(u for u, _ in taus):.1f}-{max(u for u, _ in taus):.1f}, down "
                f"{min(d for _, d in taus):.1f}-{max(d for _, d in taus):.1f} ms; real-time "
                f"factor {rt['real_time_factor']:.3f}, longest wait "
                f"{1e3 * rt['longest_wait_s']:.0f} ms")
    _tables(flights)
    print(f"\n(flights' JSON in {tmp})")
    for n in notes:
        print(f"- {n}")
    return 0


def _reread(folder: Path) -> int:
    from bench.commands.fly import _log_report  # the log read as fly reads it

    flights: dict[str, list[dict]] = {}
    for path in sorted(folder.glob("*-[0-9]*.json")):
        out = json.loads(path.read_text())
        out.update(_log_report(Path(out["flight_run"])))
        d = out["design"]
        label = (f"{path.stem.rsplit('-', 1)[0]} {d['propeller']}+{d['motor']}+"
                 f"{d['battery']}")
        flights.setdefault(label, []).append(out)
    _tables(flights)
    return 0


def _tables(flights: dict[str, list[dict]]) -> None:
    """The Markdown tables of docs/flight.md from the flights' JSON, per design."""
    print("Angle steps (ANGLE mode, 10 deg stick step, the plant's attitude):\n")
    print("| design | maneuver | rise cascade (ms) | rise BF in the loop (ms) | "
          "overshoot cascade (%) | overshoot BF in the loop (%) |")
    print("| --- | --- | ---: | ---: | ---: | ---: |")
    for label, outs in flights.items():
        for man in ("roll_step", "pitch_step"):
            c = outs[0]["cascade"]["maneuvers"][man]
            f = [o["maneuvers"][man] for o in outs]
            print(f"| {label} | {man} | {_f(c['rise_time_ms'])} | "
                  f"{_span([x['rise_time_ms'] for x in f])} | {_f(c['overshoot_pct'], '.1f')} | "
                  f"{_span([x['overshoot_pct'] for x in f], '.1f')} |")
    print("\nRate steps (acro, +-100 deg/s stick steps; medians over a flight's steps):\n")
    print("| design | axis | rise BF in the loop, plant rate (ms) | rise log, gyro direct (ms) | "
          "rise log, deconvolved H1 (ms) | overshoot in the loop (%) | overshoot log direct "
          "(%) | overshoot log H1 (%) | steps a flight: loop; log |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for label, outs in flights.items():
        for name, axis in (("roll", "x"), ("pitch", "y")):
            loop = [o["rate_steps"][name] for o in outs]
            log = [o["log_step_response"][axis] for o in outs]
            print(f"| {label} | {name} | {_span([x['rise_ms'] for x in loop])} | "
                  f"{_span([x['direct_rise_ms'] for x in log])} | "
                  f"{_span([x['h1'].get('rise_ms') for x in log])} | "
                  f"{_span([x['overshoot_pct'] for x in loop], '.1f')} | "
                  f"{_span([x.get('direct_overshoot_pct') for x in log], '.1f')} | "
                  f"{_span([x['h1'].get('overshoot_pct') for x in log], '.1f')} | "
                  f"{', '.join(str(x['steps']) for x in loop)}; "
                  f"{', '.join(str(x['direct_steps']) for x in log)} |")
    print("\nDeconvolved (H1) rise against the direct median of the same flight's steps:\n")
    for label, outs in flights.items():
        for axis in ("x", "y"):
            for k, o in enumerate(outs):
                r = o["log_step_response"][axis]
                h1, d = r["h1"].get("rise_ms"), r["direct_rise_ms"]
                rises = r["direct_rises_ms"]
                mean = sum(rises) / len(rises) if rises else None
                rel = (f"{100 * (h1 / d - 1):+.0f} %" if h1 and d else "-")
                print(f"- {label} {axis} flight {k + 1}: H1 {_f(h1, '.1f')} ms, direct median "
                      f"{_f(d, '.1f')} (mean {_f(mean, '.1f')}) over {len(rises)} steps: "
                      f"H1 {rel}")


if __name__ == "__main__":
    sys.exit(main())
