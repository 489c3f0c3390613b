"""Measure the static thrust map of the default simulated rig and store it with the rig.

Paper C section 4.4: thrust against command from slow, settled holds. This is what
``rotorbench sweep`` does on any rig; this script makes the default rig's side file
(``bench/data/rigs/sim.thrust_map.csv``) reproducible without the bench CLI:

    .venv/bin/python benchmarks/sim_thrust_map.py [RIG.toml] [--hold SECONDS]

Hold each level for several rotor time constants (the default 0.8 s suits the 30 ms rotor
of sim.toml; sim-thesis-e.toml's 14 in rotor, tau ~130 ms, was measured with --hold 2).
"""

from __future__ import annotations

import argparse

import numpy as np

from bench.rig.rig import default_rig_path, load_rig, save_thrust_map
from drivers.factory import open_rig


def measure(rig_path: str, step_us: float = 25.0, hold_s: float = 0.8) -> tuple[np.ndarray, ...]:
    rig = load_rig(rig_path)
    dt = 0.02
    with open_rig(rig) as r:
        cell = r.sensors["load_cell"]

        def hold(pulse: float, seconds: float) -> np.ndarray:
            chunks = []
            for _ in range(round(seconds / dt)):
                r.esc.set_pulse_us(pulse)
                r.clock.sleep(dt)
                chunks.append(cell.read_block().values["thrust_n"])
            tail = round(0.25 * seconds / dt)  # settled part: the last quarter
            return np.concatenate(chunks[-tail:])

        r.esc.arm()
        tare = float(hold(rig.esc.idle_us, 0.5).mean())
        cmds = np.arange(rig.esc.min_us, rig.esc.max_us + step_us / 2, step_us)
        thrust = np.array([hold(c, hold_s).mean() - tare for c in cmds])
    return cmds, thrust


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rig", nargs="?", default=str(default_rig_path()))
    ap.add_argument("--hold", type=float, default=0.8, help="seconds per level")
    args = ap.parse_args()
    path = args.rig
    cmds, thrust = measure(path, hold_s=args.hold)
    rig = save_thrust_map(load_rig(path), cmds, np.round(thrust, 4))
    for c, f in zip(cmds, thrust, strict=True):
        print(f"{c:7.1f} us  {f:7.3f} N")
    print(f"wrote {rig.thrust_map_path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
