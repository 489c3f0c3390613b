"""A trajectory upload that takes time (a real controller over TCP) does not put the
motion late against the recorded plan, and the next upload is not refused as "moving".

The simulated hexapod uploads in zero simulated time, which hid both. ``SlowUploads``
gives it a real controller's upload: it takes ``upload_s`` on the rig clock and is refused
while a trajectory runs (PI GCS, drivers/backends/pi_hexapod.py).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from bench.plan_runner.runner import HexapodRunner, HexapodRunOptions
from bench.plans.calibration_sequences import Move, Rest, SetPivot, compile_plan
from bench.plans.sequences import Sequence
from bench.rig.rig import default_imu_rig_path, load_imu_rig
from drivers.contracts import POSE_CHANNELS
from drivers.errors import DeviceError
from drivers.factory import open_rig
from drivers.hexapod_motions import lever_arm_motion

RIG = load_imu_rig(default_imu_rig_path())
MOVES = (lever_arm_motion("x", duration_s=4.0), lever_arm_motion("y", duration_s=4.0))
SEQ = Sequence("latency", (SetPivot(), Rest(0.5, "lever_x"), Move(MOVES[0], "lever_x"),
                                      Rest(0.5, "lever_x"), Move(MOVES[1], "lever_y"),
                                      Rest(0.5, "lever_y")))
UPLOAD_S = 0.8  # longer than the rest between the two moves


class SlowUploads:
    """The simulated hexapod with an upload that takes rig time and is refused while moving;
    notes the rig time of every start."""

    def __init__(self, hexapod: Any, clock: Any, upload_s: float,
                 sleep: Callable[[float], None] | None = None) -> None:
        """``sleep``: what the upload takes its time on (default the rig clock; ``time.sleep``
        for host time, as a real controller's over TCP or RS-232)."""
        self._hexapod, self._clock, self.upload_s = hexapod, clock, upload_s
        self._sleep = sleep or clock.sleep
        self.started_at: list[float] = []
        self.stuck = False  # True: reports moving for ever once started (a hung controller)

    def is_moving(self) -> bool:
        return (self.stuck and bool(self.started_at)) or self._hexapod.is_moving()

    def upload(self, trajectory: Any) -> None:
        if self._hexapod.is_moving():
            raise DeviceError(f"upload of {trajectory.name!r} refused while moving")
        self._sleep(self.upload_s)
        self._hexapod.upload(trajectory)

    def start(self) -> None:
        self.started_at.append(self._clock.now())
        self._hexapod.start()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._hexapod, name)


@pytest.fixture
def bench():
    b = open_rig(RIG)
    b.hexapod = SlowUploads(b.hexapod, b.clock, UPLOAD_S)  # type: ignore[assignment]
    yield b
    b.close()


def _run(bench, **options: Any) -> tuple[HexapodRunner, dict[str, np.ndarray]]:
    chunks: list[dict[str, np.ndarray]] = []
    runner = HexapodRunner(bench, compile_plan(SEQ, RIG.hexapod.hexapod_limits()),
                           options=HexapodRunOptions(tick_s=0.1, **options),
                           on_rows=lambda rows: chunks.append(dict(rows)))
    runner.run()
    rows = {k: np.concatenate([c[k] for c in chunks]) for k in chunks[0]}
    return runner, rows


def test_motion_follows_the_recorded_plan_despite_slow_uploads(bench) -> None:
    runner, rows = _run(bench)
    assert runner.result is not None and runner.result.status == "success", runner.result
    starts = np.asarray(bench.hexapod.started_at) - runner._t0
    assert len(starts) == 2
    t, step = rows["t_s"], rows["step"]
    move_steps = [s.index for s in runner.plan.segments if s.kind == "move"]
    for k, t0, motion in zip(move_steps, starts, MOVES, strict=True):
        tk = t[step == k]
        # the move's rows are exactly the motion: from its start, for its duration
        assert t0 <= tk[0] < t0 + 0.0101 and tk[-1] <= t0 + motion.duration_s + 1e-9
        assert tk[-1] - tk[0] > motion.duration_s - 0.0101
        pose, _, _ = motion.evaluate(tk - t0)
        got = np.column_stack([rows[c][step == k] for c in POSE_CHANNELS])
        assert np.abs(got - pose).max() < 1e-4
    at_rest = ~np.isin(step, move_steps)
    omega = np.column_stack([rows[f"ref_omega_{a}_rad_s"] for a in "xyz"])
    assert np.abs(omega[at_rest]).max() < 1e-9  # no motion under a rest label
    assert runner.result.t_end_s == pytest.approx(runner.plan.duration_s + 2 * UPLOAD_S,
                                                  abs=0.11)
    assert not bench.hexapod.is_moving()


def test_a_motion_that_does_not_end_ends_the_run_safely(bench) -> None:
    hx = bench.hexapod
    hx.stuck = True
    with pytest.raises(DeviceError, match=r"still moving 1\.\d+ s after it should have stopped "
                                          r"\(step 2 'lever_x'"):
        _run(bench, motion_end_timeout_s=1.0)
    assert len(hx.started_at) == 1  # the second motion was never uploaded
    hx.stuck = False
    assert hx.stop_calls >= 1 and not hx.is_moving()


def test_an_upload_longer_than_the_host_watchdog_does_not_stop_the_run() -> None:
    """The hexapod is at rest while a trajectory uploads (the controller refuses an upload
    while moving), so the upload's length is not a stalled host. It was: a real controller
    takes seconds for a long trajectory, and the 1 s watchdog ended the run 'command loop
    stalled' before the motion began."""
    b = open_rig(RIG)
    b.hexapod = SlowUploads(b.hexapod, b.clock, 0.5, time.sleep)  # type: ignore[assignment]
    try:
        runner, rows = _run(b, watchdog_timeout_s=0.3)
    finally:
        b.close()
    assert runner.result is not None and runner.result.status == "success", runner.result
    assert len(b.hexapod.started_at) == 2 and len(rows["t_s"]) > 0
