"""Benchmark: Paper C Step 1 (20 repeats) on the simulated rig at 25 kHz, wall time and
real-time factor, with and without recording, for several command-loop ticks; also the
runner without its batches of ticks (``bench.engine.run_loop``: one read per tick, as on
hardware) to show what the batches gain. ``step_command.py`` times the whole command.

The rig is a temporary copy of the default sim rig; its static thrust map is taken from
the plant's steady state (no sweep), so only the step run is timed. Prints measured
numbers; nothing here is asserted.
"""

from __future__ import annotations

import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bench.engine.safety import effective_limits  # noqa: E402
from bench.plan_runner.runner import Runner, RunOptions  # noqa: E402
from bench.plan_runner.session import esc_range_of, plan_for, run_sequence  # noqa: E402
from bench.plans.stand_sequences import step1  # noqa: E402
from bench.rig.rig import default_rig_path, load_rig, save_thrust_map  # noqa: E402
from drivers.factory import open_rig  # noqa: E402

REPEATS = 3


def mapped_rig(tmp: Path):
    path = tmp / "sim.toml"
    path.write_text(default_rig_path().read_text(encoding="utf-8"), encoding="utf-8")
    rig = load_rig(path)
    devices = open_rig(rig)
    truth = devices.truth()
    devices.close()
    grid = np.arange(1100.0, 1951.0, 10.0)
    return save_thrust_map(rig, grid.tolist(), [truth.steady_thrust_n(u) for u in grid])


def time_recorded(rig, tmp: Path, tick: float) -> tuple[list[float], float, int]:
    walls = []
    for i in range(REPEATS):
        t0 = time.perf_counter()
        out = run_sequence(rig, step1(repeats=20), tmp / f"runs-{tick}-{i}", open_rig,
                           options=RunOptions(tick_s=tick))
        walls.append(time.perf_counter() - t0)
        assert out.result.status == "success", out.result.reason
    return walls, out.result.t_end_s, out.result.rows


class TickByTick(Runner):
    """The runner reading every device on every tick (no batches of ticks)."""

    batches = False


def time_unrecorded(rig, tick: float, runner_class: type[Runner] = Runner) -> list[float]:
    seq = step1(repeats=20)
    walls = []
    for _ in range(REPEATS):
        devices = open_rig(rig)
        runner = runner_class(devices, plan_for(rig, seq), esc_range_of(rig),
                        effective_limits(rig.limits, seq.limits), None, RunOptions(tick_s=tick))
        t0 = time.perf_counter()
        result = runner.run()
        walls.append(time.perf_counter() - t0)
        devices.close()
        assert result.status == "success", result.reason
    return walls


def time_plant_only(rig, duration: float, tick: float) -> float:
    """The simulated devices alone: sleep + read every sensor, no runner."""
    devices = open_rig(rig)
    t0 = time.perf_counter()
    for _ in range(round(duration / tick)):
        devices.clock.sleep(tick)
        for s in devices.sensors.values():
            s.read_block()
    wall = time.perf_counter() - t0
    devices.close()
    return wall


class _NullClock:
    t = 0.0

    def now(self) -> float:
        return self.t

    def sleep(self, dt: float) -> None:
        self.t += dt


class _NullEsc:
    def arm(self) -> None: ...

    def set_pulse_us(self, us: float) -> None: ...

    def disarm(self) -> None: ...


class _BlockSource:
    """A sensor that hands out ready 25 kHz blocks at no cost beyond making the arrays."""

    def __init__(self, clock: _NullClock, names: tuple[str, ...]) -> None:
        self.clock, self.names, self.last = clock, names, 0.0

    def describe(self):
        from drivers.contracts import ChannelInfo, DeviceInfo

        return DeviceInfo("null", "null", "null://",
                          tuple(ChannelInfo(n, "", 25_000.0) for n in self.names))

    def read_block(self):
        from drivers.contracts import Block

        n = round((self.clock.t - self.last) * 25_000.0)
        t = self.last + np.arange(1, n + 1) / 25_000.0
        self.last = self.clock.t
        return Block(t, {k: np.ones(n) for k in self.names})


def time_runner_alone(rig, tick: float) -> float:
    """The runner's own cost per run: the same plan on devices that cost nothing."""

    class Devices:
        clock = _NullClock()
        esc = _NullEsc()

    dev = Devices()
    dev.sensors = {"load_cell": _BlockSource(dev.clock, ("thrust_n",)),
                   "power": _BlockSource(dev.clock, ("current_a", "voltage_v")),
                   "rpm": _BlockSource(dev.clock, ("rpm",))}
    seq = step1(repeats=20)
    runner = Runner(dev, plan_for(rig, seq), esc_range_of(rig), {"thrust_n": 100.0}, None,
                    RunOptions(tick_s=tick))
    t0 = time.perf_counter()
    assert runner.run().status == "success"
    return time.perf_counter() - t0


def main() -> int:
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        rig = mapped_rig(tmp)
        duration = plan_for(rig, step1(repeats=20)).duration_s
        print(f"Step 1, 20 repeats, default sim rig (25 kHz load cell, current, voltage, rpm): "
              f"{duration:.1f} s of rig time; best and median of {REPEATS} runs")
        print(f"{'tick_s':>7} {'what':<28} {'best_s':>7} {'median_s':>8} {'x realtime':>10}")
        for tick in (0.01, 0.02, 0.05):
            walls, t_end, rows = time_recorded(rig, tmp, tick)
            plain = time_unrecorded(rig, tick)
            ticked = time_unrecorded(rig, tick, TickByTick)
            plant = time_plant_only(rig, duration, tick)
            alone = [time_runner_alone(rig, tick) for _ in range(REPEATS)]
            for what, w in (("runner + recorder (full)", walls), ("runner, no recorder", plain),
                            ("  same, tick by tick", ticked),
                            ("sim devices, read per tick", [plant]),
                            ("runner on null devices", alone)):
                best, med = min(w), statistics.median(w)
                print(f"{tick:>7.2f} {what:<28} {best:>7.3f} {med:>8.3f} {duration / best:>10.1f}")
        print(f"rows per run: {rows} ({rows / t_end:.0f} rows/s of rig time)")
        print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the end")

    return 0


if __name__ == "__main__":
    sys.exit(main())
