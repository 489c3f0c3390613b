"""A dead bench against the real firmware: what the motor does after SIGKILL.

Each test starts Betaflight 4.6.0 SITL in its own network namespace (``tests/sitl.py``),
feeds it FDM and reads its motor output (UDP 9001) itself, so the firmware and its output
outlive the bench. The bench is a child process (``nsenter`` into that namespace) that
opens a rig whose ESC is ``msp+tcp://127.0.0.1:5761`` (no ``launch``: the launcher would
stop the firmware with the bench), commands a steady 1400 us on every tick, as the
command loop does, and is SIGKILLed:

* the motor test (``propellers_off = true``) keeps 1400 us: Betaflight has no motor-test
  timeout, which is why it opens only with ``propellers_off = true``;
* the RC path (the default without ``propellers_off``) goes to idle and then disarms: the
  firmware's receiver failsafe, because the bench's ``MSP_SET_RAW_RC`` frames stop.

No UDP RC packet is ever sent here: it would switch the firmware's receiver from MSP to
UDP for good, and UDP RC never times out. Numbers: docs/protocols.md, "A dead host stops
the motor".
"""

from __future__ import annotations

import math
import os
import signal
import socket
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from rotorbench_tests_sitl import Fdm

from bench.rig.rig import load_rig
from drivers.backends.msp_rc_esc import MspRcEsc
from drivers.codecs import msp
from drivers.codecs.sitl import FDM_PORT, MOTOR_RAW_PORT, MSP_PORT, decode_motor_raw
from drivers.factory import open_rig

pytestmark = pytest.mark.slow(wall_s=40)

factory_rigs = sys.modules["rotorbench_tests_factory_rigs"]  # factory_rigs.py, by conftest

ROOT = Path(__file__).resolve().parents[2]
RIGS = ROOT / "bench" / "data" / "rigs"
URL = f"msp+tcp://127.0.0.1:{MSP_PORT}"
HELD_US = 1400
IDLE_US = 1055  # armed low: 1000 + motor_idle 5.5 %
IDLE_BOUND_S = 1.0  # SIGKILL to idle: the 300 ms channel hold, then the firmware's RX task
STOP_BOUND_S = 2.0  # SIGKILL to disarmed: failsafe_delay_s 1.0, then the next FDM reply

BENCH = f"""
import sys, time
from bench.rig.rig import load_rig
from drivers.factory import open_rig
rig = open_rig(load_rig(sys.argv[1]))
rig.esc.arm()
rig.esc.set_pulse_us({HELD_US})
print("ready", flush=True)
while True:  # the command loop: the same command on every tick
    rig.esc.set_pulse_us({HELD_US})
    time.sleep(0.02)
"""


class MotorOutput:
    """The firmware's motor 1 on UDP 9001 (``servo_packet_raw``), each update timed."""

    def __init__(self, sitl) -> None:
        with sitl.inside():
            self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self.sock.bind(("127.0.0.1", MOTOR_RAW_PORT))
        self.sock.settimeout(0.1)
        self.log: list[tuple[float, float]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.sock.recv(256)
            except OSError:
                continue
            try:
                motor_us = decode_motor_raw(data).motor_us
            except ValueError:  # not a servo_packet_raw
                continue
            self.log.append((time.monotonic(), motor_us[0]))

    @property
    def last(self) -> float:
        return self.log[-1][1] if self.log else float("nan")

    def since(self, t0: float) -> list[tuple[float, float]]:
        return [(t - t0, v) for t, v in self.log if t >= t0]

    def wait(self, what: str, cond, timeout_s: float) -> float:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if self.log and cond(self.last):
                return time.monotonic()
            time.sleep(0.002)
        pytest.fail(f"motor output: {what} not within {timeout_s:g} s (last {self.last})")

    def close(self) -> None:
        self._stop.set()
        self._thread.join(1.0)
        self.sock.close()


def _rig(tmp_path: Path, options: str) -> Path:
    body = f'url = "{URL}"\noptions = {{ motor = 0, timeout_s = 2.0{options} }}'
    return factory_rigs.write(tmp_path, {"esc": body}, RIGS / "sim-serial.toml")


def _bench(sitl, rig: Path, tmp_path: Path) -> subprocess.Popen[str]:
    """The bench as a child in the firmware's namespace; returns once it commands 1400."""
    with open(tmp_path / "bench.err", "w") as err:
        proc = subprocess.Popen(
            ["nsenter", f"--net=/proc/{sitl.proc.pid}/ns/net", sys.executable, "-c", BENCH,
             str(rig)], cwd=ROOT, stdout=subprocess.PIPE, stderr=err, text=True,
            start_new_session=True)
    assert proc.stdout is not None
    line = proc.stdout.readline()
    if line.strip() != "ready":
        _kill(proc)
        pytest.fail(f"bench child: {(tmp_path / 'bench.err').read_text()[-2000:]}")
    return proc


def _kill(proc: subprocess.Popen[str]) -> None:
    """SIGKILL the bench child (its session: nsenter and python)."""
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(5)
    if proc.stdout is not None:
        proc.stdout.close()


@pytest.fixture
def fed(sitl):
    """The SITL fed a resting FDM stream at 250 Hz, its motor output read. FDM starts
    after the first MSP reply and the first motor update is awaited, as the launched rig
    does: FDM sent earlier often left the firmware's gyro task (and its output, baro
    calibration and RX processing) dead for good (docs/sim-rig.md)."""
    with sitl.inside():
        sock = socket.create_connection(("127.0.0.1", MSP_PORT), 2.0)
    with sock:
        sock.settimeout(3.0)
        sock.sendall(msp.request(msp.MSP_API_VERSION))
        assert sock.recv(64)[:3] == b"$M>"
    out = MotorOutput(sitl)
    sitl.feed(FDM_PORT, Fdm().packet, 250.0)
    try:
        out.wait("the first motor update", lambda v: v == v, 1.0)
        yield sitl, out
    finally:
        out.close()


def test_a_killed_bench_leaves_the_motor_test_running(fed, tmp_path):
    sitl, out = fed
    bench = _bench(sitl, _rig(tmp_path, ", propellers_off = true"), tmp_path)
    out.wait("1400 us", lambda v: v == HELD_US, 2.0)
    _kill(bench)
    t_kill = time.monotonic()
    time.sleep(3.0)
    after = out.since(t_kill)
    assert len(after) > 500  # the firmware kept sending (one update per FDM packet)...
    assert {v for _, v in after} == {HELD_US}  # ...and every one still 1400 us
    print(f"motor test: still {HELD_US} us {after[-1][0]:.2f} s after SIGKILL "
          f"({len(after)} updates)")
    with sitl.inside():  # clean up: the value only goes with a new motor test command
        rig = open_rig(load_rig(_rig(tmp_path, ", propellers_off = true")))
    with rig:
        rig.esc.arm()
    out.wait("1000 us after the clean-up", lambda v: v == 1000, 1.0)


def test_a_killed_bench_on_the_rc_path_stops_the_motor(fed, tmp_path):
    sitl, out = fed
    idle, off = [], []
    for _ in range(2):  # the second bench re-arms the same firmware after its failsafe
        bench = _bench(sitl, _rig(tmp_path, ""), tmp_path)
        out.wait("1400 us", lambda v: abs(v - HELD_US) <= 3, 2.0)
        t_kill = time.monotonic()
        _kill(bench)
        out.wait("disarmed", lambda v: v == 1000, STOP_BOUND_S + 1.0)
        after = out.since(t_kill)
        idle.append(next(t for t, v in after if v <= IDLE_US))
        off.append(next(t for t, v in after if v == 1000))
    print(f"RC path, SIGKILL to idle: {[round(t, 3) for t in idle]} s, to disarmed: "
          f"{[round(t, 3) for t in off]} s (median {statistics.median(off):.3f})")
    assert min(idle) > 0.1  # the failsafe, not the kill itself: RXLOSS needs 150 ms
    assert max(idle) < IDLE_BOUND_S
    assert max(off) < STOP_BOUND_S


def _command_until(esc, out: MotorOutput, us: float) -> None:
    """Command ``us`` every 20 ms for 0.5 s and on until the output is within 3 us of it
    (the firmware's RC smoothing and throttle boost shape each step), at most 2 s."""
    t0 = time.monotonic()
    while True:
        esc.set_pulse_us(us)
        time.sleep(0.02)
        elapsed = time.monotonic() - t0
        if elapsed > 0.5 and abs(out.last - us) <= 3.0:
            return
        assert elapsed < 2.0, f"motor output {out.last} us, commanded {us} us"


def test_the_rc_path_follows_the_command_and_ends_disarmed(fed, tmp_path):
    sitl, out = fed
    with sitl.inside():
        rig = open_rig(load_rig(_rig(tmp_path, "")))
    with rig:
        esc = rig.esc
        assert isinstance(esc, MspRcEsc)  # no propellers_off: the RC path
        assert esc.describe().extra["control"] == "rc"
        esc.arm()
        assert esc.client.armed()
        out.wait("armed idle", lambda v: v == IDLE_US, 1.0)
        t_first = math.nan
        for us in (1200.0, 1500.0, 1800.0, 1300.0, 1600.0):
            _command_until(esc, out, us)
            t_first = time.monotonic() if math.isnan(t_first) else t_first
        # no receiver failsafe while the bench lived: it would show as idle (the channel
        # hold ended) or 1000 us (disarmed) between commands that never went below 1200
        assert min(v for _, v in out.since(t_first)) > 1200 - 5
        assert esc.client.armed()
        print(f"RC path: {esc.frames} frames, longest gap while armed "
              f"{esc.max_frame_gap_s * 1e3:.0f} ms")
    # closed: throttle low, ARM off, the FC says disarmed and the motor is at 1000
    out.wait("1000 us", lambda v: v == 1000, 1.0)
    assert sitl.alive()
