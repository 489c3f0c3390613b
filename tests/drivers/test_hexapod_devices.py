"""Contract tests of the IMU-bench devices: the simulated hexapod, IMU and reference IMU."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.rig.rig import default_imu_rig_path, load_imu_rig
from drivers.contracts import (
    HEXAPOD_LOG_CHANNELS,
    IMU_CHANNELS,
    REFERENCE_IMU_CHANNELS,
    Block,
    DeviceInfo,
    Fault,
    Hexapod,
    HexapodLimitError,
    HexapodLimits,
    Sensor,
    Trajectory,
)
from drivers.errors import DeviceError
from drivers.factory import open_rig
from drivers.hexapod_motions import gyro_sines, lever_arm_motion, verification_motion
from drivers.sim.hexapod import SimHexapod


@pytest.fixture
def bench():
    rig = open_rig(load_imu_rig(default_imu_rig_path()))
    yield rig
    rig.close()


def test_devices_fill_their_contracts(bench) -> None:
    assert isinstance(bench.hexapod, Hexapod)
    for sensor, names in ((bench.imu, IMU_CHANNELS), (bench.reference_imu,
                                                       REFERENCE_IMU_CHANNELS)):
        assert isinstance(sensor, Sensor)
        info = sensor.describe()
        assert isinstance(info, DeviceInfo)
        assert tuple(c.name for c in info.channels) == names
    info = bench.hexapod.describe()
    assert info.kind == "hexapod"
    assert tuple(c.name for c in info.channels) == HEXAPOD_LOG_CHANNELS
    assert info.extra["limits"] == bench.hexapod.limits().as_dict()


def test_blocks_are_new_samples_only_with_increasing_stamps(bench) -> None:
    seen: dict[str, list[Block]] = {"imu": [], "ref": [], "hex": []}
    for _ in range(7):
        bench.clock.sleep(0.033)
        seen["imu"].append(bench.imu.read_block())
        seen["ref"].append(bench.reference_imu.read_block())
        seen["hex"].append(bench.hexapod.read_log())
    for blocks, rate in ((seen["imu"], 100.0), (seen["ref"], 100.0), (seen["hex"], 1000.0)):
        t = np.concatenate([b.t_s for b in blocks])
        assert np.all(np.diff(t) > 0)
        assert np.allclose(np.diff(t), 1.0 / rate)
    assert len(bench.imu.read_block()) == 0  # nothing new without time passing


def test_hexapod_follows_the_trajectory_and_reports_body_frame_truth(bench) -> None:
    motion = verification_motion(duration_s=8.0)
    hx = bench.hexapod
    hx.upload(Trajectory.from_motion(motion, 200.0))
    hx.start()
    assert hx.is_moving()
    bench.clock.sleep(motion.duration_s + 0.5)
    assert not hx.is_moving()
    log = hx.read_log()
    # The analytic motion's acceleration jumps where the raised-cosine fade ends and begins
    # (t = 0, 1 s, duration - 1 s, duration); the platform's spline rounds those corners off.
    d = motion.duration_s
    corners = np.min(np.abs(log.t_s[:, None] - np.array([0.0, 1.0, d - 1.0, d])), axis=1) < 0.05
    inside = (log.t_s <= motion.duration_s) & ~corners
    truth = SimHexapod().follow(motion, log.t_s[inside])  # the analytic motion
    w = np.c_[[log.values[f"ref_omega_{a}_rad_s"][inside] for a in "xyz"]].T
    f = np.c_[[log.values[f"ref_acc_{a}_m_s2"][inside] for a in "xyz"]].T
    # the platform follows the spline through the 200 Hz samples: within 0.1 % of the peak
    assert np.abs(w - truth.omega_b_rad_s).max() < 1e-3 * np.abs(truth.omega_b_rad_s).max()
    assert np.abs(f - truth.specific_force_b_m_s2).max() < 1e-3
    at_rest = log.t_s > motion.duration_s
    assert np.allclose(log.values["ref_acc_z_m_s2"][at_rest], 9.80665)
    assert np.allclose(log.values["hex_vx_m_s"][at_rest], 0.0)


def test_trajectory_beyond_a_limit_is_refused_naming_it(bench) -> None:
    hx = bench.hexapod
    fast = lever_arm_motion("x", amplitude_deg=5.0, freq_hz=3.0, duration_s=5.0)
    with pytest.raises(HexapodLimitError, match="rate_rad_s") as err:
        hx.upload(Trajectory.from_motion(fast, 200.0))
    assert "refused" in str(err.value) and "lever_x" in str(err.value)
    with pytest.raises(DeviceError, match="without an uploaded"):
        hx.start()
    assert not hx.is_moving()


def test_trajectory_must_start_at_the_present_pose(bench) -> None:
    t = np.arange(100) / 100.0
    poses = np.zeros((100, 6))
    poses[:, 0] = 0.01 + 0.001 * t  # starts 10 mm away
    with pytest.raises(DeviceError, match="away from the present pose"):
        bench.hexapod.upload(Trajectory("jump", 100.0, poses))


def test_stop_freezes_the_platform_and_is_always_allowed(bench) -> None:
    hx = bench.hexapod
    hx.stop()  # at rest: harmless
    hx.upload(Trajectory.from_motion(gyro_sines(beats=1), 200.0))
    hx.start()
    bench.clock.sleep(3.0)
    hx.stop()
    hx.stop()
    assert not hx.is_moving()
    pose_then, _, _ = hx.kinematics_at(np.array([bench.clock.now()]))
    bench.clock.sleep(1.0)
    log = hx.read_log()
    late = log.t_s > 3.0 + 1e-9
    assert np.allclose(log.values["hex_roll_rad"][late], pose_then[0, 3])
    assert np.allclose(log.values["ref_omega_x_rad_s"][late], 0.0)


def test_a_stopped_run_ends_exactly_where_it_was_stopped() -> None:
    """Seen in a loaded test run: started at 1.08231501 s, stopped at 3.883613346 s, and
    t0 + (stop - t0) = 3.8836133460000006, so the hexapod still reported motion at the
    stop time, which a paused bench clock read again."""
    from drivers.sim.hexapod_device import _Run

    run = _Run("wave", 1.08231501, None, 22.0)  # type: ignore[arg-type]
    run.stopped_at = 3.883613346
    assert run.t_end == 3.883613346
    assert not run.t0 <= 3.883613346 < run.t_end  # is_moving's test at the stop time
    assert _Run("w", 1.0, None, 2.0).t_end == 3.0  # type: ignore[arg-type]


def test_pivot_and_start_are_refused_while_moving(bench) -> None:
    hx = bench.hexapod
    hx.upload(Trajectory.from_motion(gyro_sines(beats=1), 200.0))
    hx.start()
    bench.clock.sleep(1.0)
    with pytest.raises(DeviceError, match="pivot"):
        hx.set_pivot((0.0, 0.0, 0.1))
    with pytest.raises(DeviceError):
        hx.start()
    hx.stop()
    hx.set_pivot((0.0, 0.0, 0.1))
    assert hx.describe().extra["pivot_m"] == [0.0, 0.0, 0.1]


def test_imu_stamps_lag_the_hexapod_clock_by_the_offset(bench) -> None:
    """The IMU sample stamped t holds the motion at hexapod time t - offset."""
    motion = lever_arm_motion("z", duration_s=6.0)
    bench.hexapod.upload(Trajectory.from_motion(motion, 200.0))
    bench.hexapod.start()
    bench.clock.sleep(5.0)
    b = bench.imu.read_block()
    m = bench.sim.model
    gyro = np.c_[[b.values[c] for c in IMU_CHANNELS[:3]]].T
    w_body = (gyro - np.asarray(m.gyro_bias_rad_s)) @ m.k_gyro().T
    truth = SimHexapod().follow(motion, b.t_s - m.clock_offset_s)
    unshifted = SimHexapod().follow(motion, b.t_s)
    err = np.sqrt(np.mean((w_body[:, 2] - truth.omega_b_rad_s[:, 2]) ** 2))
    err0 = np.sqrt(np.mean((w_body[:, 2] - unshifted.omega_b_rad_s[:, 2]) ** 2))
    assert err < 0.01 < err0  # noise 0.006 rad/s; the 23.7 ms lag alone costs more


def test_imu_range_quantisation_and_noise(bench) -> None:
    bench.clock.sleep(20.0)
    b = bench.imu.read_block()
    m = bench.sim.model
    gyro = np.c_[[b.values[c] for c in IMU_CHANNELS[:3]]].T
    acc = np.c_[[b.values[c] for c in IMU_CHANNELS[3:]]].T
    assert np.allclose(gyro / m.gyro_lsb_rad_s, np.round(gyro / m.gyro_lsb_rad_s))
    assert np.allclose(acc / m.acc_lsb_m_s2, np.round(acc / m.acc_lsb_m_s2))
    sg, _ = m.noise_std()
    assert np.allclose(gyro.std(axis=0), sg, rtol=0.1)
    assert np.allclose(gyro.mean(axis=0), m.gyro_bias_rad_s, atol=4 * sg / math.sqrt(len(b)))
    assert np.abs(gyro).max() <= m.gyro_range_rad_s


def test_reference_imu_gives_the_platform_attitude_scalar_first(bench) -> None:
    motion = verification_motion(duration_s=6.0)
    bench.hexapod.upload(Trajectory.from_motion(motion, 200.0))
    bench.hexapod.start()
    bench.clock.sleep(4.0)
    b = bench.reference_imu.read_block()
    q = np.c_[[b.values[c] for c in REFERENCE_IMU_CHANNELS[:4]]].T
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0)
    assert np.all(q[:, 0] > 0.99)  # scalar first: small angles have w near 1
    truth = SimHexapod().follow(motion, b.t_s)
    r_true = Rotation.from_euler("ZYX", truth.euler_rad[:, ::-1])
    angle = (Rotation.from_quat(q, scalar_first=True) * r_true.inv()).magnitude()
    assert np.degrees(angle).max() < 1.0  # 0.1 deg noise per axis


def test_lever_arm_is_measured_from_the_pivot(bench) -> None:
    r = np.asarray(bench.sim.model.lever_arm_m)
    assert np.allclose(bench.imu.lever_arm_from_pivot(), r)
    bench.hexapod.set_pivot((0.0, 0.0, 0.05))
    assert np.allclose(bench.imu.lever_arm_from_pivot(), r - [0.0, 0.0, 0.05])


def test_same_seed_same_samples() -> None:
    cfg = load_imu_rig(default_imu_rig_path())
    out = []
    for seed in (3, 3, 4):
        with open_rig(cfg, seed=seed) as rig:
            rig.clock.sleep(0.5)
            out.append(rig.imu.read_block().values["imu_gyro_x_rad_s"])
    assert np.array_equal(out[0], out[1]) and not np.array_equal(out[0], out[2])


@pytest.mark.parametrize("fault", [Fault.DISCONNECT, Fault.TIMEOUT])
def test_faults_raise_device_errors_and_stop_still_freezes(bench, fault) -> None:
    bench.hexapod.upload(Trajectory.from_motion(gyro_sines(beats=1), 200.0))
    bench.hexapod.start()
    bench.imu.inject(fault, at_s=0.5)
    bench.hexapod.inject(fault, at_s=0.5)
    bench.clock.sleep(1.0)
    with pytest.raises(DeviceError):
        bench.imu.read_block()
    with pytest.raises(DeviceError):
        bench.hexapod.read_log()
    with pytest.raises(DeviceError):
        bench.hexapod.stop()  # the reply is lost ...
    assert not bench.hexapod.is_moving()  # ... but the platform stopped


def test_limits_dataclass_and_trajectory_validation() -> None:
    lim = HexapodLimits()
    assert set(lim.as_dict()) == set(HexapodLimits.names())
    with pytest.raises(DeviceError, match="poses must be"):
        Trajectory("bad", 100.0, np.zeros((5, 3)))
    with pytest.raises(DeviceError, match="non-finite"):
        Trajectory("bad", 100.0, np.full((5, 6), np.nan))


def test_non_sim_urls_name_what_the_backend_lacks(tmp_path) -> None:
    text = default_imu_rig_path().read_text(encoding="utf-8").replace(
        'url = "sim://hexapod"', 'url = "tcp://192.168.0.10:50000"')
    path = tmp_path / "real.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(DeviceError, match=r"hexapod.*real IMU under test.*tcp://sim"):
        open_rig(load_imu_rig(path))


def test_rig_file_faults_reach_the_simulated_devices(tmp_path) -> None:
    text = default_imu_rig_path().read_text(encoding="utf-8").replace(
        '[devices.imu]\nurl = "sim://imu"',
        '[devices.imu]\nurl = "sim://imu"\noptions = {faults = [{kind = "disconnect", '
        'at_s = 0.2}]}')
    path = tmp_path / "faulty.toml"
    path.write_text(text, encoding="utf-8")
    with open_rig(load_imu_rig(path)) as rig:
        rig.clock.sleep(0.1)
        rig.imu.read_block()
        rig.clock.sleep(0.2)
        with pytest.raises(DeviceError, match="disconnected"):
            rig.imu.read_block()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('"disconnect"', '"melt"'), encoding="utf-8")
    with pytest.raises(DeviceError, match="imu: bad fault spec"):
        open_rig(load_imu_rig(bad))
