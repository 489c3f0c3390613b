"""A simulated sensor's readings on its sample grid, a block at a time: the same readings as
one at a time, never stale after the plant changed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.rig.rig import load_imu_rig
from drivers.contracts import Trajectory
from drivers.sim_worlds import build_sim_imu_rig
from drivers.wire_sim.grid_sampler import GridSampler
from drivers.wire_sim.plant_peers import FC_LOOP_HZ, _PlantImu

REPO = Path(__file__).resolve().parents[2]


class _Plant:
    """A plant whose reading at ``t`` is ``level + t``; ``level`` changes with a version."""

    def __init__(self) -> None:
        self.level, self.version, self.calls = 0.0, 0, 0

    def readings(self, t: np.ndarray) -> np.ndarray:
        self.calls += 1
        return np.column_stack([t, self.level + t])


def test_rows_are_the_readings_at_the_grid_times_held_until_the_next() -> None:
    plant = _Plant()
    grid = GridSampler(plant.readings, 0.01, origin_s=0.5, block=8, version=lambda: 0)
    assert grid.at(0.5) == [0.5, 0.5]
    assert grid.at(0.5349)[0] == pytest.approx(0.53)  # sample and hold: the last one taken
    assert grid.at(0.54)[0] == pytest.approx(0.54)
    assert [grid.row(k)[0] for k in range(20)] == pytest.approx(0.5 + 0.01 * np.arange(20))
    assert plant.calls == 3  # rows 0-7, 8-15, 16-19: a block per call, not a call per row


def test_a_changed_plant_is_read_anew_never_from_a_block_computed_before() -> None:
    plant = _Plant()
    grid = GridSampler(plant.readings, 0.01, block=100, version=lambda: plant.version)
    assert grid.at(0.1)[1] == pytest.approx(0.1)  # the block up to t = 1.09 is computed
    plant.level, plant.version = 5.0, 1
    assert grid.at(0.2)[1] == pytest.approx(5.2)
    plant.level = 7.0  # unannounced: the block stays (what the version is for)
    assert grid.at(0.3)[1] == pytest.approx(5.3)


def test_prefetch_computes_the_next_block_before_a_reading_needs_it() -> None:
    plant = _Plant()
    grid = GridSampler(plant.readings, 0.01, block=10, version=lambda: 0)
    grid.prefetch(0.0)
    grid.prefetch(0.03)  # first half of rows 0-9: nothing to do
    assert plant.calls == 1
    grid.prefetch(0.06)  # second half: rows 6-15 now
    assert plant.calls == 2
    assert [grid.at(t)[0] for t in (0.06, 0.1, 0.15)] == pytest.approx([0.06, 0.1, 0.15])
    assert plant.calls == 2


def test_the_fc_reads_its_loop_sample_of_the_motion_started_after_its_block() -> None:
    """The simulated FC's IMU: the reading an MSP reply carries is the model's own
    (``SimImuDevice.sample_at``) at the loop sample taken last ``clock_offset_s`` before
    the request; a trajectory started after a block was computed is in the next reading."""
    sim = build_sim_imu_rig(load_imu_rig(REPO / "bench" / "data" / "rigs" /
                                         "sim-imu-wire.toml"), 0, None)
    offset = sim.model.clock_offset_s
    imu = _PlantImu(sim, sim.clock)
    sim.clock.sleep(0.2)
    _, gyro_at_rest, _ = imu(0.0)
    assert np.abs(np.subtract(gyro_at_rest, sim.model.gyro_bias_rad_s)).max() < 0.05
    t = np.linspace(0.0, 2 * np.pi, 1001)
    poses = np.zeros((t.size, 6))
    poses[:, 5] = 0.2 * (1 - np.cos(t))  # yaw: 0.2 rad/s at most
    sim.hexapod.upload(Trajectory("yaw", 1001 / (2 * np.pi), poses))
    sim.hexapod.start()
    sim.clock.sleep(0.09)  # the sample is within the block computed at rest
    _, gyro, (_, _, yaw) = imu(0.0)
    assert imu.grid.blocks_computed == 2
    sampled = np.floor((sim.clock.now() - offset) * FC_LOOP_HZ + 1e-9) / FC_LOOP_HZ
    truth = sim.hexapod.state_at(np.array([sampled]))
    assert yaw == pytest.approx(float(truth.euler_rad[0, 2]), abs=1e-12) and yaw > 1e-4
    model = sim.model
    expected = truth.omega_b_rad_s[0] @ model.forward_gyro().T + model.gyro_bias_rad_s
    assert np.abs(np.subtract(gyro, expected)).max() < 0.05  # the model's noise
