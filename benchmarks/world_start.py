"""How long a simulated-device world takes to start: forked by the zygote, or in a fresh
interpreter (how every world started before ``drivers/wire_sim/world_forks.py``).

Both ways build the same world with the same ``serve``; the fresh way runs it as
``python -c`` that imports ``drivers.wire_sim.world_process`` and serves, as
``python -m drivers.wire_sim.world_process`` did. Per start it measures the wall time until
the world has answered that it is built, and the world process's CPU by then
(``/proc/PID/stat``); it prints the medians of ``--starts`` starts each way and their
ratio, for a one-device world (the PI controller) and the IMU bench's wire world (numpy,
scipy's rotations). The zygote's own start, once per host process, is printed apart.

Usage: ``python benchmarks/world_start.py [--starts N]`` (Linux: pidfds and /proc).
"""

from __future__ import annotations

import argparse
import os
import socket
import statistics
import subprocess
import sys
import time
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

FRESH = ("import os, sys; from multiprocessing.connection import Connection; "
         "from drivers.wire_sim.world_process import serve; "
         "serve(Connection(int(sys.argv[1])), os.pidfd_open(int(sys.argv[2])))")


def cpu_s(pid: int) -> float:
    """User and system CPU of process ``pid`` so far."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def fresh_start(build: Any, args: tuple) -> tuple[float, float]:
    ours, theirs = socket.socketpair()
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-c", FRESH, str(theirs.fileno()),
                             str(os.getpid())], pass_fds=(theirs.fileno(),), env=env,
                            stdin=subprocess.DEVNULL, start_new_session=True)
    theirs.close()
    conn = Connection(ours.detach())
    conn.send((build, args))
    assert conn.recv() == ("ok", None)
    wall, cpu = time.perf_counter() - t0, cpu_s(proc.pid)
    conn.send(("stop", None, (), ()))
    proc.wait(10)
    conn.close()
    return wall, cpu


def forked_start(build: Any, args: tuple) -> tuple[float, float]:
    from drivers.wire_sim.world_process import WorldProcess

    t0 = time.perf_counter()
    world = WorldProcess(build, *args)
    wall, cpu = time.perf_counter() - t0, cpu_s(world.process.pid)
    world.close()
    return wall, cpu


def worlds() -> dict[str, tuple[Any, tuple]]:
    from bench.rig.rig import default_rig_path, load_imu_rig
    from drivers.sim_worlds import imu_wire_world
    from drivers.wire_sim.pi_hexapod import SimPiController
    from drivers.wire_sim.world_process import one_device

    rig = load_imu_rig(default_rig_path().parent / "sim-imu-wire.toml")
    return {"one device (PI controller)": (one_device, (SimPiController, {})),
            "IMU bench wire world": (imu_wire_world, (rig, None, 6.0, time.monotonic()))}


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--starts", type=int, default=8)
    args = parser.parse_args(argv)
    cases = worlds()
    first = next(iter(cases.values()))
    wall, _ = forked_start(*first)  # starts the zygote
    print(f"the zygote's own start with the first fork: {wall:.2f} s of wall time")
    print(f"{'world':28} {'fresh wall':>11} {'forked wall':>12} {'ratio':>6} "
          f"{'fresh CPU':>10} {'forked CPU':>11} {'ratio':>6}")
    for name, (build, build_args) in cases.items():
        fresh = [fresh_start(build, build_args) for _ in range(args.starts)]
        forked = [forked_start(build, build_args) for _ in range(args.starts)]
        fw, fc = (statistics.median(x) for x in zip(*fresh, strict=True))
        kw, kc = (statistics.median(x) for x in zip(*forked, strict=True))
        print(f"{name:28} {fw:10.3f}s {kw:11.3f}s {fw / kw:6.1f} {fc:9.3f}s {kc:10.3f}s "
              f"{fc / max(kc, 0.01):6.1f}")
    print(f"(medians of {args.starts} starts each, one after another; CPU is the world "
          f"process's own until it answered, at {1 / os.sysconf('SC_CLK_TCK'):.2f} s ticks)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
