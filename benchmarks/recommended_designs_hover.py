"""Does every design ``optimize`` recommends fly? (hover with control margin)

The thesis' model has no thrust limit, so its optimum can be a drone that cannot take off
(4 x P1 + M1 + B3 on thesis-e, thrust-to-weight 0.73). This script asks the three commands a
user would type, as the user types them: ``optimize --catalog C --actuators N --objective O
--json`` for N = 4, 6, 8 and three objectives, then ``evaluate ... --json``
(thrust_to_weight) and ``fly ... --json`` (hover.can_hover) of the design it recommends, on
thesis-e and on the SizingLab catalogs imported from fixtures/data. It prints one Markdown
row per recommendation and exits 1 if any has T/W below the margin or cannot hover.

Usage: ``python benchmarks/recommended_designs_hover.py [--payload-kg KG] [--thesis-rules]``
(``--thesis-rules`` shows what the thesis' model recommends without the hover check).
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
OBJECTIVES = ("flight-time", "time-constant", "price")
ACTUATORS = (4, 6, 8)
MARGIN = 1.2  # the default --min-thrust-to-weight


def rotorbench_json(*argv: str) -> tuple[int, dict]:
    proc = subprocess.run([str(ROTORBENCH), *argv, "--json"], capture_output=True, text=True,
                          check=False)
    if proc.returncode not in (0, 3):
        raise SystemExit(f"rotorbench {' '.join(argv)}: exit {proc.returncode}: {proc.stderr}")
    return proc.returncode, json.loads(proc.stdout)


def rows_for(label: str, catalog: str, payload: str, extra: list[str]) -> list[list[str]]:
    rows = []
    for n in ACTUATORS:
        for objective in OBJECTIVES:
            code, doc = rotorbench_json("optimize", "--catalog", catalog, "--actuators", str(n),
                                        "--objective", objective, "--payload-kg", payload,
                                        *extra)
            best = doc["best"]
            if best is None:
                rows.append([label, str(n), objective, f"none (exit {code})", "", "", "", ""])
                continue
            ids = ["--catalog", catalog, "--actuators", str(n), "--propeller",
                   best["propeller"], "--motor", best["motor"], "--battery", best["battery"],
                   "--payload-kg", payload]
            _, sheet = rotorbench_json("evaluate", *ids)
            _, flown = rotorbench_json("fly", *ids, "--maneuver", "roll_step")
            ratio, hover = sheet["thrust_to_weight"], flown["hover"]
            ok = ratio >= MARGIN and hover["can_hover"]
            rows.append([label, str(n), objective,
                         f"{best['propeller']} / {best['motor']} / {best['battery']}",
                         f"{ratio:.2f}", f"{hover['throttle']:.2f}",
                         "yes" if hover["can_hover"] else f"no: {hover['note']}",
                         "ok" if ok else "FAIL"])
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--payload-kg", default="0")
    parser.add_argument("--thesis-rules", action="store_true")
    args = parser.parse_args(argv)
    extra = ["--thesis-rules"] if args.thesis_rules else []
    with tempfile.TemporaryDirectory(prefix="rotorbench-hover-") as tmp:
        sizinglab = str(Path(tmp) / "sizinglab")
        subprocess.run([str(ROTORBENCH), "import-sizinglab", "--source",
                        str(ROOT / "optimizer" / "data" / "sizinglab"), "--out", sizinglab],
                       check=True, capture_output=True)
        rows = rows_for("thesis-e", "thesis-e", args.payload_kg, extra)
        rows += rows_for("SizingLab", sizinglab, args.payload_kg, extra)
    head = ["catalog", "N", "objective", "recommended P / M / B", "T/W (evaluate)",
            "hover throttle (fly)", "can hover (fly)", f"T/W >= {MARGIN} and hovers"]
    print(f"payload {args.payload_kg} kg, " + ("--thesis-rules" if extra else "default margin"))
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for row in rows:
        print("| " + " | ".join(row) + " |")
    failed = [r for r in rows if r[-1] != "ok"]
    print(f"{len(rows) - len(failed)} of {len(rows)} recommendations hover with margin")
    return 1 if failed and not extra else 0


if __name__ == "__main__":
    sys.exit(main())
