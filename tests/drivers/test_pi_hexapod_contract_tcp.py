"""The Hexapod contract through the real PI GCS backend, over loopback TCP, against the
simulated controller driven by the simulated hexapod plant (``tcp://sim`` rigs).

Mirrors the simulated hexapod's contract tests (tests/drivers/test_hexapod_devices.py)
and adds what only a wire has: the bytes sent, a busy conversation, a dropped connection.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest

from bench.rig.rig import load_imu_rig
from drivers.backends.pi_hexapod import GcsDialect, PiHexapod
from drivers.codecs import gcs
from drivers.contracts import (
    HEXAPOD_LOG_CHANNELS,
    DeviceInfo,
    Hexapod,
    HexapodLimitError,
    Trajectory,
)
from drivers.errors import DeviceError
from drivers.factory import open_rig
from drivers.hexapod_motions import gyro_sines, lever_arm_motion, verification_motion
from drivers.sim.hexapod import SimHexapod

REPO = Path(__file__).resolve().parents[2]
TCP_RIG = REPO / "bench" / "data" / "rigs" / "sim-imu-tcp.toml"


@pytest.fixture
def bench():
    rig = open_rig(load_imu_rig(TCP_RIG))
    yield rig
    rig.close()


def _channels(block, names):
    return np.c_[[block.values[n] for n in names]].T


def test_the_backend_fills_the_contract_with_the_rig_files_limits(bench) -> None:
    hx = bench.hexapod
    assert isinstance(hx, PiHexapod) and isinstance(hx, Hexapod)
    info = hx.describe()
    assert isinstance(info, DeviceInfo) and info.kind == "hexapod"
    assert tuple(c.name for c in info.channels) == HEXAPOD_LOG_CHANNELS
    rig = load_imu_rig(TCP_RIG)
    assert info.extra["limits"] == hx.limits().as_dict() == rig.hexapod.hexapod_limits().as_dict()
    assert info.extra["log_rate_hz"] == pytest.approx(1000.0)
    assert "C-887" in info.model


def test_log_at_rest_is_new_samples_only_with_increasing_stamps(bench) -> None:
    blocks = []
    for _ in range(7):
        bench.clock.sleep(0.033)
        blocks.append(bench.hexapod.read_log())
    t = np.concatenate([b.t_s for b in blocks])
    assert np.all(np.diff(t) > 0) and np.allclose(np.diff(t), 1e-3)
    assert t[-1] == pytest.approx(bench.clock.now(), abs=1e-3)
    assert len(bench.hexapod.read_log()) == 0  # nothing new without time passing
    acc = np.concatenate([b.values["ref_acc_z_m_s2"] for b in blocks])
    assert np.allclose(acc, 9.80665)


def test_follows_the_trajectory_and_logs_the_body_frame_truth(bench) -> None:
    """The recorder's positions, differentiated by the backend, against the plant's
    exact state at the same instants."""
    motion = verification_motion(duration_s=6.0)
    hx = bench.hexapod
    hx.upload(Trajectory.from_motion(motion, 200.0))
    t_start = bench.clock.now()
    hx.start()
    assert hx.is_moving()
    blocks = []
    while bench.clock.now() < t_start + motion.duration_s + 0.5:
        bench.clock.sleep(0.05)
        blocks.append(hx.read_log())
    assert not hx.is_moving()
    t = np.concatenate([b.t_s for b in blocks])
    log = {c: np.concatenate([b.values[c] for b in blocks]) for c in HEXAPOD_LOG_CHANNELS}
    assert np.all(np.diff(t) > 0) and np.allclose(np.diff(t), 1e-3)
    truth = bench.sim.hexapod.state_at(t)
    w = np.c_[[log[f"ref_omega_{a}_rad_s"] for a in "xyz"]].T
    alpha = np.c_[[log[f"ref_alpha_{a}_rad_s2"] for a in "xyz"]].T
    f = np.c_[[log[f"ref_acc_{a}_m_s2"] for a in "xyz"]].T
    peak_w = np.abs(truth.omega_b_rad_s).max()
    assert peak_w > 0.1
    assert np.abs(w - truth.omega_b_rad_s).max() < 1e-3 * peak_w
    # Accelerations are fitted (11 ms Savitzky-Golay) to positions printed to 1e-6 mm and
    # 1e-6 deg; the fit rounds off where the motion's acceleration jumps (its fades at 1 s
    # and d - 1 s, the start and the end, where the plant jumps to rest at once).
    d = motion.duration_s
    corners = np.min(np.abs(t[:, None] - t_start - np.array([0.0, 1.0, d - 1.0, d])),
                     axis=1) < 0.008
    assert np.abs(f - truth.specific_force_b_m_s2)[~corners].max() < 0.01
    assert np.abs(f - truth.specific_force_b_m_s2)[corners].max() < 0.2
    assert np.sqrt(np.mean((alpha - truth.alpha_b_rad_s2)[~corners] ** 2)) < 0.005
    assert np.allclose(log["hex_roll_rad"], truth.euler_rad[:, 0], atol=1e-7)
    # and the uploaded path is the motion itself (as on the plain simulated hexapod)
    inside = (t - t_start > 1.1) & (t - t_start < motion.duration_s - 1.1)
    analytic = SimHexapod().follow(motion, t[inside] - t_start)
    assert np.abs(w[inside] - analytic.omega_b_rad_s).max() < 1e-3 * peak_w
    at_rest = t > t_start + motion.duration_s + 0.01
    assert at_rest.sum() > 400
    assert np.allclose(log["ref_acc_z_m_s2"][at_rest], 9.80665)
    assert np.allclose(log["hex_vx_m_s"][at_rest], 0.0)


def _rig_with(tmp_path: Path, options: str) -> Path:
    path = tmp_path / "tcp.toml"
    path.write_text(TCP_RIG.read_text(encoding="utf-8").replace(
        'url = "tcp://sim"', f'url = "tcp://sim"\noptions = {{ {options} }}'), encoding="utf-8")
    return path


def test_plain_differences_on_request_and_bad_options_named(tmp_path: Path) -> None:
    """``derivative_window = 3``: 3-point differences of the recorded positions (second
    order one-sided at the run's ends) instead of the Savitzky-Golay fit."""
    with open_rig(load_imu_rig(_rig_with(tmp_path, "derivative_window = 3"))) as b:
        motion = lever_arm_motion("y", duration_s=3.0)
        b.hexapod.upload(Trajectory.from_motion(motion, 200.0))
        b.hexapod.start()
        b.clock.sleep(motion.duration_s + 0.1)
        log = b.hexapod.read_log()
        truth = b.sim.hexapod.state_at(log.t_s)
        inside = log.t_s < motion.duration_s  # the plant is at rest from the last instant
        alpha = log.values["ref_alpha_y_rad_s2"][inside]
        err = alpha - truth.alpha_b_rad_s2[inside, 1]
        assert np.sqrt(np.mean(err ** 2)) < 0.03 < np.abs(alpha).max()
    for options, message in (("derivative_window = 4", "odd number"),
                             ("wave_chunk_points = 0", "must be positive"),
                             ('pivot_letters = "RST"', "unknown option")):
        with pytest.raises(DeviceError, match=message) as err:
            open_rig(load_imu_rig(_rig_with(tmp_path, options)))
        assert "tcp.toml: [devices.hexapod] options" in str(err.value)


def test_back_to_back_runs_keep_one_gapless_log(bench) -> None:
    """A second start restarts the recorder: what was left of the first run is read first."""
    hx = bench.hexapod
    motion = lever_arm_motion("z", duration_s=2.0)
    for _ in range(2):
        hx.upload(Trajectory.from_motion(motion, 200.0))
        hx.start()
        bench.clock.sleep(motion.duration_s + 0.2)  # no log read in between
    log = hx.read_log()
    assert np.allclose(np.diff(log.t_s), 1e-3) and log.t_s[-1] == pytest.approx(4.4)
    truth = bench.sim.hexapod.state_at(log.t_s)
    assert np.abs(log.values["ref_omega_z_rad_s"] - truth.omega_b_rad_s[:, 2]).max() < 1e-3


def test_upload_speaks_wave_tables_and_the_data_recorder(bench) -> None:
    wire = bench.wire
    hx = bench.hexapod
    traj = Trajectory.from_motion(lever_arm_motion("z", duration_s=3.0), 200.0)
    hx.upload(traj)
    wav = [c for c in wire.commands if c.name == "WAV"]
    assert len(wav) == 6 * int(np.ceil(len(traj.poses) / 100))
    first_w = next(c for c in wav if c.args[0] == "6")
    assert first_w.args[1:5] == ("X", "PNT", "1", "100")
    assert all(c.args[1] == "&" for c in wav if c.args[0] == "6" and c is not first_w)
    w_deg = np.concatenate([[float(v) for v in c.args[5:]] for c in wav if c.args[0] == "6"])
    assert np.allclose(w_deg, np.degrees(traj.poses[:, 5]), atol=1e-9)  # degrees on the wire
    args = {c.name: c.args for c in wire.commands}
    assert args["WTR"][1] == "50"  # 200 Hz = 50 servo cycles of 100 us per point
    assert args["RTR"] == ("10",)  # the recorder at 1 kHz
    assert [c.args for c in wire.commands if c.name == "DRC"] == [
        (str(k), a, "2") for k, a in enumerate("XYZUVW", 1)]  # actual position
    assert not hx.is_moving()  # nothing moves before start
    hx.start()
    (wgo,) = [c for c in wire.commands if c.name == "WGO"]
    assert wgo.args == ("1", "1", "2", "1", "3", "1", "4", "1", "5", "1", "6", "1")
    bench.clock.sleep(0.2)
    hx.read_log()
    assert "DRR?" in [c.name for c in wire.commands]


def test_trajectory_beyond_a_limit_is_refused_naming_it_before_any_bytes(bench) -> None:
    hx = bench.hexapod
    fast = lever_arm_motion("x", amplitude_deg=5.0, freq_hz=3.0, duration_s=5.0)
    with pytest.raises(HexapodLimitError, match="rate_rad_s") as err:
        hx.upload(Trajectory.from_motion(fast, 200.0))
    assert "refused" in str(err.value) and "lever_x" in str(err.value)
    assert "WAV" not in [c.name for c in bench.wire.commands]
    with pytest.raises(DeviceError, match="without an uploaded"):
        hx.start()
    assert not hx.is_moving()


def test_trajectory_must_start_at_the_present_pose(bench) -> None:
    poses = np.zeros((100, 6))
    poses[:, 0] = 0.01 + 0.001 * np.arange(100) / 100.0  # starts 10 mm away
    with pytest.raises(DeviceError, match="away from the present pose"):
        bench.hexapod.upload(Trajectory("jump", 100.0, poses))


def test_a_rate_that_is_not_whole_servo_cycles_is_refused(bench) -> None:
    with pytest.raises(DeviceError, match="servo cycles"):
        bench.hexapod.upload(Trajectory.from_motion(gyro_sines(beats=1), 300.0))


def test_stop_freezes_the_platform_and_is_always_allowed(bench) -> None:
    hx, plant = bench.hexapod, bench.sim.hexapod
    hx.stop()  # at rest: harmless, never raises
    hx.upload(Trajectory.from_motion(gyro_sines(beats=1), 200.0))
    hx.start()
    bench.clock.sleep(3.0)
    hx.read_log()
    hx.stop()
    hx.stop()
    assert not hx.is_moving() and not plant.is_moving()
    frozen = plant.kinematics_at(np.array([bench.clock.now()]))[0][0]
    assert np.abs(frozen[3:]).max() > 0.01  # stopped mid-motion, away from home
    bench.clock.sleep(1.0)
    log = hx.read_log()
    late = log.t_s > 3.0 + 2e-3
    assert late.sum() > 900
    assert np.allclose(log.values["hex_roll_rad"][late], frozen[3], atol=1e-7)
    assert np.allclose(log.values["ref_omega_x_rad_s"][late], 0.0)
    assert bench.wire.error == 0  # error 10 of the stop was read and cleared


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
    assert bench.sim.hexapod.pivot_m == pytest.approx((0.0, 0.0, 0.1))  # the plant's pivot
    assert bench.wire.pivot == pytest.approx({"R": 0.0, "S": 0.0, "T": 100.0})  # mm, R S T


def test_stop_from_another_thread_while_a_reply_is_pending(bench) -> None:
    """The watchdog's stop does not wait for a stuck conversation: it goes over the
    second connection and the platform stops while the main thread still waits."""
    hx, plant, wire = bench.hexapod, bench.sim.hexapod, bench.wire
    hx.upload(Trajectory.from_motion(gyro_sines(beats=1), 200.0))
    hx.start()
    bench.clock.sleep(2.0)
    wire.stall(1.5, connection=0)  # the main connection's next reply comes 1.5 s late
    asked = wire.by_connection[0].count("#9")
    waiting = threading.Thread(target=hx.is_moving)
    waiting.start()
    end = time.monotonic() + 5.0
    while wire.by_connection[0].count("#9") == asked and time.monotonic() < end:
        time.sleep(0.005)  # until the controller has the question (and the reply is late)
    t0 = time.monotonic()
    hx.stop()
    took = time.monotonic() - t0
    stopped_while_waiting = waiting.is_alive()
    waiting.join()
    assert not plant.is_moving()
    assert stopped_while_waiting and took < 1.0
    assert "#24" in wire.by_connection[1]  # the stop connection carried it


def test_a_dropped_connection_fails_loudly_and_stop_reconnects(bench) -> None:
    hx, plant, wire = bench.hexapod, bench.sim.hexapod, bench.wire
    hx.upload(Trajectory.from_motion(gyro_sines(beats=1), 200.0))
    hx.start()
    bench.clock.sleep(2.0)
    hx.read_log()
    wire.drop_connections()
    bench.clock.sleep(0.1)
    assert plant.is_moving()  # the controller carries on without its host ...
    with pytest.raises(DeviceError, match=r"closed the connection|send failed"):
        hx.read_log()
    hx.stop()  # ... until the backend reconnects to stop it
    assert not plant.is_moving()
    assert len(wire.by_connection) == 3 and "#24" in wire.by_connection[2]


def test_stop_raises_only_when_nothing_can_carry_it(tmp_path: Path) -> None:
    with open_rig(load_imu_rig(_rig_with(tmp_path, "timeout_s = 0.3"))) as b:
        b.wire.disconnect()  # silent controller: every reply is lost
        t0 = time.monotonic()
        with pytest.raises(DeviceError, match="stop not confirmed"):
            b.hexapod.stop()
        assert time.monotonic() - t0 < 3.0  # main, stop and a new connection: 0.3 s each


def test_the_simulated_controller_survives_malformed_commands(bench) -> None:
    hx = bench.hexapod
    for line in (b"WTR 1\n", b"WSL 1 x\n", b"DRC 1 X\n", b"WAV 1 X PNT 1 3 0 0\n",
                 b"WGO 7 1\n", b"DRR? 1 10 9\n"):
        with pytest.raises(DeviceError, match=r"GCS error (1|17|26) "):
            hx.query(line) if b"?" in line else hx.command(line)
    assert "C-887" in gcs.parse_idn(hx.query(gcs.idn())).model  # still answering


def test_dialect_options_are_checked() -> None:
    assert GcsDialect.from_options({"pivot_axes": ["A", "B", "C"]}, "w").pivot_axes == \
        ("A", "B", "C")
    with pytest.raises(DeviceError, match=r"w: unknown option\(s\) 'baud'") as err:
        GcsDialect.from_options({"baud": 9600}, "w")
    assert err.value.exit_code == 2
    with pytest.raises(DeviceError, match="three letters"):
        GcsDialect.from_options({"pivot_axes": ["R"]}, "w")
