"""The simulated devices' own process: serves its world, reports errors, dies with its parent."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from bench.rig.rig import default_rig_path, load_rig
from drivers.device_priority import DEVICE_NICE, session_group_nice
from drivers.errors import DeviceError
from drivers.sim_worlds import wire_plant

serial = pytest.importorskip("serial")

REPO = Path(__file__).resolve().parents[2]
RIG = default_rig_path().parent / "sim-serial.toml"


def _gone(pid: int, within_s: float) -> bool:
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.02)
    return False


def test_a_board_in_the_world_process_prints_on_its_pty() -> None:
    wire = wire_plant(load_rig(RIG))
    try:
        from drivers.codecs.loadcell_lines import TESTSTAND_V2

        board = wire.start_peer("serial:loadcell", "loadcell", (TESTSTAND_V2, 0.004))
        pid = wire.plant.world.process.pid
        assert pid != os.getpid()
        # a device's process: in a scheduling group of its own, raised where it may be
        assert os.getsid(pid) == pid
        if os.geteuid() == 0:
            assert session_group_nice(pid) in (DEVICE_NICE, None)
        with serial.Serial(board.path, 115_200, timeout=1.0) as port:
            port.write(b"\n")
            assert port.readline().startswith(b"Load cell ready")
            assert len(port.read(200)) == 200  # lines keep coming
        assert board.get("started") is True  # an attribute read there
        with pytest.raises(DeviceError, match="no_such_method"):
            board.no_such_method()  # the world's error, named
    finally:
        wire.close()
    assert _gone(wire.plant.world.process.pid, 5.0)
    assert not wire.peers


CHILD = r"""
import sys
from bench.rig.rig import load_rig
from drivers.sim_worlds import wire_plant
wire = wire_plant(load_rig(sys.argv[1]))
print(wire.plant.world.process.pid, flush=True)
sys.stdin.read()
"""


def test_the_world_process_does_not_outlive_a_killed_parent() -> None:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    host = subprocess.Popen([sys.executable, "-c", CHILD, str(RIG)], env=env, cwd=REPO,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert host.stdout is not None
        world_pid = int(host.stdout.readline())
        host.send_signal(signal.SIGKILL)
        host.wait(timeout=10)
    finally:
        if host.poll() is None:
            host.kill()
        host.communicate()
    assert _gone(world_pid, 5.0), "the world's process outlived its parent"


def test_the_imu_worlds_device_errors_keep_their_words() -> None:
    """The IMU bench's world in its process: a device that cannot start says why, as it
    would in the host's (a DeviceError's message crosses the pipe as it is)."""
    import socket

    from bench.rig.rig import load_imu_rig
    from drivers.sim_worlds import imu_world_process
    from drivers.wire_sim.imu_world import HostPacedClock

    clock = HostPacedClock(6.0)
    world = imu_world_process(load_imu_rig(RIG.parent / "sim-imu-wire.toml"), None, clock)
    try:
        with socket.create_server(("127.0.0.1", 0)) as taken:
            port = taken.getsockname()[1]
            with pytest.raises(DeviceError, match=r"^cannot start the simulated controller "
                                                  rf"on port {port} "):
                world.start("tcp:sim", "hexapod", (port,))
        assert world.start("tcp:sim", "hexapod", (0,)).address[1] > 0
        with clock.hold():  # held in the world too: its clock reads what the host's does
            held = clock.now()
            time.sleep(0.05)
            assert world.process.request("call", None, ("clock", "now")) == held
        assert abs(world.process.request("call", None, ("clock", "now")) - clock.now()) < 0.05
    finally:
        world.close()
    assert _gone(world.process.process.pid, 5.0)


def test_the_firmware_peers_liveness_is_read_without_a_request() -> None:
    """The bench asks before every command whether the firmware's output still reaches the
    plant; the answer must not wait on the world's process (a busy one held the command
    loop past its watchdog), yet a world stopped for long, or a deaf firmware, is told."""
    from drivers.wire_sim.sitl_plant import WORLD_SILENT_S

    wire = wire_plant(load_rig(RIG))
    peer = wire.sitl_peer(0, 250.0).start()  # no firmware listens: it will never answer
    try:
        peer.check()  # just started: not yet silent for long
        pid = wire.plant.world.process.pid
        os.kill(pid, signal.SIGSTOP)  # the world's process does nothing at all
        try:
            t0 = time.monotonic()
            peer.check()
            assert time.monotonic() - t0 < 0.05  # answered here, not there
            time.sleep(WORLD_SILENT_S + 0.2)
            with pytest.raises(DeviceError, match="plant's process has not answered"):
                peer.check()
        finally:
            os.kill(pid, signal.SIGCONT)
        deadline = time.monotonic() + 2.0
        while time.monotonic() < deadline:
            try:
                peer.check()
            except DeviceError as exc:
                if "motor output stopped" in str(exc):
                    break
            time.sleep(0.02)
        else:
            pytest.fail("the deaf firmware was never reported")
    finally:
        peer.stop()
        wire.close()


def test_the_hosts_clock_never_reads_ahead_of_the_held_worlds() -> None:
    """A hold (a trajectory upload) stops bench time in the world's process and here. The
    world's answer to ``freeze`` takes a round trip; were this clock still running
    meanwhile, a reading here would be ahead of the world's held time, and an MSP poll sent
    then would pair a late send stamp with the held FC clock (its offset estimate, the
    largest over 400 rows, then stamps 4 s of rows late by that round trip)."""
    from drivers.wire_sim.imu_world import HostPacedClock
    from drivers.wire_sim.paced_clock import PacedClock

    class SlowWorldClock:  # the world's clock, 50 ms of request away
        def __init__(self, epoch: float) -> None:
            self.clock = PacedClock(6.0, max_gap_s=math.inf, epoch=epoch)
            self.held_ns: int | None = None

        def freeze(self) -> int:
            time.sleep(0.025)
            self.held_ns = self.clock.freeze()
            time.sleep(0.025)
            return self.held_ns

        def resume(self) -> float:
            return self.clock.resume()

    host = HostPacedClock(6.0)
    world = SlowWorldClock(host.epoch)
    host.world = world  # type: ignore[assignment]
    readings: list[int] = []
    done = threading.Event()

    def read() -> None:
        while not done.is_set():
            readings.append(host.now_ns())
            time.sleep(0.001)

    reader = threading.Thread(target=read)
    reader.start()
    try:
        time.sleep(0.01)
        held = host.freeze()
        time.sleep(0.01)
    finally:
        done.set()
        reader.join()
    assert held == world.held_ns
    assert max(readings) <= world.held_ns
    host.resume()
    assert abs(host.now() - world.clock.now()) < 0.01


def _parent(pid: int) -> int:
    with open(f"/proc/{pid}/stat") as stat:  # "pid (comm) state ppid ..."
        return int(stat.read().rsplit(")", 1)[1].split()[1])


def test_worlds_are_forked_by_one_zygote_and_outlive_it() -> None:
    """Each world is forked from this process's zygote (one interpreter that imported the
    devices once), in a session of its own; a zygote that died is started again, and the
    worlds it forked serve on without it."""
    from drivers.wire_sim import world_forks
    from drivers.wire_sim.pi_hexapod import SimPiController
    from drivers.wire_sim.world_process import WorldProcess, one_device

    first = WorldProcess(one_device, SimPiController, {}, name="sim-pi")
    second = WorldProcess(one_device, SimPiController, {}, name="sim-pi")
    try:
        zygote = _parent(first.process.pid)
        assert zygote == _parent(second.process.pid) != os.getpid()
        assert os.getsid(first.process.pid) == first.process.pid != os.getsid(0)
        assert world_forks._zygote is not None and world_forks._zygote.process.pid == zygote
        os.kill(zygote, signal.SIGKILL)
        world_forks._zygote.process.wait(5.0)
        assert first.remote("device").get("referenced") in (True, False)  # still serving
        third = WorldProcess(one_device, SimPiController, {}, name="sim-pi")
        try:
            assert _parent(third.process.pid) not in (zygote, os.getpid())
        finally:
            third.close()
        second.process.kill()  # its handle ends it by its pidfd
        assert second.process.wait(5.0) == -1 and second.process.poll() == -1
        with pytest.raises(DeviceError, match="sim-pi: the simulated devices' process is gone"):
            second.remote("device").get("referenced")
    finally:
        first.close()
        second.close()
    assert _gone(first.process.pid, 5.0)
