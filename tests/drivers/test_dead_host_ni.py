"""A dead host stops the NI-DAQmx pulse train: the train is finite and renewed by the host.

The NI driver is replaced by nidaqmx's interpreter seam (as in test_backend_ni_daq.py). In
the kill -9 test the host runs in a child process whose interpreter reports every DAQmx
call to this process, which plays the counter hardware: a finite train of N pulses runs
N frames after its last start. The host is killed mid-step; the pulses must end within
``dead_host_s`` of the kill.
"""

from __future__ import annotations

import itertools
import json
import os
import signal
import subprocess
import sys
import threading
import time
from importlib.metadata import version
from pathlib import Path
from unittest import mock

import numpy as np
import pytest

nidaqmx = pytest.importorskip("nidaqmx")
if not version("nidaqmx").startswith("1."):
    pytest.skip("interpreter seam checked against nidaqmx 1.x only", allow_module_level=True)

from nidaqmx._base_interpreter import BaseInterpreter  # noqa: E402
from nidaqmx.constants import AcquisitionType  # noqa: E402

from drivers.backends import ni_daq  # noqa: E402
from drivers.errors import DeviceError  # noqa: E402

# The child: a host driving the ESC as a step does (idle, then 1800 us, renewed commands),
# its DAQmx calls reported on stdout as JSON lines with the monotonic time of each call.
CHILD = r"""
import json, sys, time
from unittest import mock
import nidaqmx
from nidaqmx._base_interpreter import BaseInterpreter
from drivers.backends import ni_daq

def report(**kw):
    sys.stdout.write(json.dumps({"t": time.monotonic(), **kw}) + "\n")
    sys.stdout.flush()

it = mock.create_autospec(BaseInterpreter, instance=True)
it.create_task.side_effect = lambda name: ("task1", True)
it.get_task_attribute_string.return_value = "task"
it.driver_version = (24, 5, 0)
it.start_task.side_effect = lambda task: report(call="start")
it.stop_task.side_effect = lambda task: report(call="stop")
it.cfg_implicit_timing.side_effect = lambda *a: report(call="timing", mode=a[1], n=a[2])
it.write_ctr_time_scalar.side_effect = lambda *a: report(call="write", high=a[3])
nidaqmx.utils._select_interpreter = lambda *a, **k: it

esc = ni_daq.NiPwmEsc(ni_daq.PwmSettings("Dev1/ctr1", frame_rate_hz=400.0, dead_host_s=0.25))
esc.arm()
report(call="stepping")
while True:  # a step at 1800 us, commanded every 10 ms like the runner's loop
    esc.set_pulse_us(1800.0)
    time.sleep(0.01)
"""


class CounterModel:
    """The counter output as hardware would run it, from the reported DAQmx calls."""

    def __init__(self) -> None:
        self.events: list[dict] = []
        self.lock = threading.Lock()

    def feed(self, stream) -> None:
        for line in stream:
            with self.lock:
                self.events.append(json.loads(line))

    def train_end(self, rate_hz: float) -> tuple[float, float, float]:
        """(time the pulses stop, width then in us, time of the last start)."""
        with self.lock:
            ev = list(self.events)
        (timing,) = [e for e in ev if e["call"] == "timing"]
        assert timing["mode"] == AcquisitionType.FINITE.value, "the pulse train must be finite"
        starts = [e["t"] for e in ev if e["call"] == "start"]
        writes = [e for e in ev if e["call"] == "write"]
        last = starts[-1]
        return last + timing["n"] / rate_hz, writes[-1]["high"] * 1e6, last


def test_kill_9_of_the_host_stops_the_pulse_train_within_dead_host_s(tmp_path):
    script = tmp_path / "host.py"
    script.write_text(CHILD, encoding="utf-8")
    repo = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": str(repo)}
    child = subprocess.Popen([sys.executable, str(script)], env=env, cwd=repo,
                             stdout=subprocess.PIPE, text=True)
    hw = CounterModel()
    reader = threading.Thread(target=hw.feed, args=(child.stdout,), daemon=True)
    reader.start()
    try:
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline:
            with hw.lock:
                starts = sum(e["call"] == "start" for e in hw.events)
                stepping = any(e["call"] == "stepping" for e in hw.events)
            if stepping and starts >= 4:  # running at 1800 us, renewed a few times
                break
            time.sleep(0.02)
        else:
            pytest.fail("the host did not start stepping in time")
        child.send_signal(signal.SIGKILL)
        killed = time.monotonic()
        child.wait(timeout=10)
    finally:
        if child.poll() is None:
            child.kill()
            child.communicate()  # reaped, pipes closed: no leak warning in a later test
    reader.join(timeout=5)
    child.stdout.close()
    end, width_us, last_start = hw.train_end(400.0)
    assert width_us == pytest.approx(1800.0)  # the motor was running when the host died
    assert last_start <= killed
    assert end - killed <= 0.25 + 1e-3, f"pulses went on {end - killed:.3f} s after the kill"
    print(f"NI-DAQmx: pulses stopped {end - killed:.3f} s after kill -9 (bound 0.25 s)")


@pytest.fixture
def interp(monkeypatch):
    it = mock.create_autospec(BaseInterpreter, instance=True)
    it.create_task.side_effect = lambda name: ("task1", True)
    it.get_task_attribute_string.return_value = "task"
    it.driver_version = (24, 5, 0)
    monkeypatch.setattr(nidaqmx.utils, "_select_interpreter", lambda *a, **k: it)
    return it


def test_live_host_renews_the_train_before_it_ends(interp):
    starts: list[float] = []
    in_force: list[float] = []  # the width in force at each renewal's start (lock held)
    made: list = []

    def start(task) -> None:
        starts.append(time.monotonic())
        if made:
            in_force.append(made[0]._pulse_us)

    interp.start_task.side_effect = start
    esc = ni_daq.NiPwmEsc(ni_daq.PwmSettings("Dev1/ctr1", frame_rate_hz=400.0,
                                             dead_host_s=0.1))
    made.append(esc)
    mode, n = interp.cfg_implicit_timing.call_args.args[1:3]
    assert mode == AcquisitionType.FINITE.value and n == 40
    esc.arm()
    t_end = time.monotonic() + 0.5
    while time.monotonic() < t_end:
        esc.set_pulse_us(1500.0)
        time.sleep(0.01)
    esc.close()
    gaps = [b - a for a, b in itertools.pairwise(starts)]
    assert len(starts) >= 5
    # each renewal comes a third of a train (0.033 s) after the last, well before the 40
    # pulses (0.1 s) run out. A loaded CI machine can stall this process for a few hundred
    # ms once (seen: 0.37 s); a real stand would then stop the motor, which is the point
    # of the finite train, so one stall is tolerated and the schedule itself is checked
    assert sorted(gaps)[len(gaps) // 2] == pytest.approx(0.1 / 3, abs=0.01), gaps
    assert sum(g >= 0.1 for g in gaps) <= 1, gaps
    # each renewal restarts the train at the width in force: 1.5 ms while the host calls,
    # idle where the guard found it silent (a stall of this process), never a stale one
    times = [c.args[3] for c in interp.set_chan_attribute_double.call_args_list]
    high, low = np.array(times[0::2]), np.array(times[1::2])
    assert high == pytest.approx(np.array(in_force) * 1e-6) and len(high) == len(in_force)
    assert high + low == pytest.approx(1 / 400.0)
    assert np.count_nonzero(high == 1.5e-3) >= len(high) - 2


def test_a_renewal_error_is_raised_by_the_next_command(interp):
    esc = ni_daq.NiPwmEsc(ni_daq.PwmSettings("Dev1/ctr1", dead_host_s=0.03))
    esc.arm()
    interp.start_task.side_effect = nidaqmx.errors.DaqError("device gone", -50405)
    time.sleep(0.1)
    with pytest.raises(DeviceError, match="renewal"):
        esc.set_pulse_us(1500.0)
    esc.close()
    with pytest.raises(DeviceError, match="dead_host_s"):
        ni_daq.PwmSettings("Dev1/ctr1", dead_host_s=0.001)
