"""The log's deconvolved rise time against the one read directly on the same flight's gyro.

Flies the test's flight (``tests/drivers/test_sitl_fly.py``: thesis-e P1+M2+B1, the catalog
actuator, hover and 9.6 s of roll and pitch rate steps, RC smoothing off) K times and prints,
per flight and axis, the rate loop's 10-90 % rise from the deconvolved step response (H1,
every window of the log pooled) and the median and mean of the gyro's own rise over the
flight's steps, and how far H1 is from each. Needs the ``sitl`` extra, root and
``unshare``; about 40 s a flight. Usage: ``python benchmarks/betaflight_rise_agreement.py
[--flights K]``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

from betaflight_loop_closed import run

DESIGN = ["--actuators", "4", "--propeller", "P1", "--motor", "M2", "--battery", "B1"]


def main() -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--flights", type=int, default=4)
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="rise-agreement-"))
    cli = tmp / "tune.txt"
    cli.write_text("set rc_smoothing = OFF\n")
    worst = {"median": 0.0, "mean": 0.0}
    for k in range(args.flights):
        out = run("fly", "--controller", "betaflight", *DESIGN, "--maneuver", "--rate-steps",
                  "9.6", "--betaflight-cli", str(cli), "--store", str(tmp / "runs"),
                  netns=True)
        for axis, r in out["log_step_response"].items():
            h1, rises = r["h1"].get("rise_ms"), r["direct_rises_ms"]
            if h1 is None or not rises:
                print(f"flight {k + 1} {axis}: no reading ({r})", flush=True)
                continue
            med, mean = statistics.median(rises), statistics.fmean(rises)
            worst["median"] = max(worst["median"], abs(h1 / med - 1))
            worst["mean"] = max(worst["mean"], abs(h1 / mean - 1))
            print(f"flight {k + 1} {axis}: H1 {h1:.1f} ms; direct over {len(rises)} steps "
                  f"median {med:.1f} ({100 * (h1 / med - 1):+.1f} %), mean {mean:.1f} "
                  f"({100 * (h1 / mean - 1):+.1f} %), single steps {min(rises):.0f}-"
                  f"{max(rises):.0f} ms", flush=True)
    print(f"largest |H1 / direct - 1|: median {100 * worst['median']:.1f} %, mean "
          f"{100 * worst['mean']:.1f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
