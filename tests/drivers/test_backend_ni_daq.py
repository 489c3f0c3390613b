"""NI-DAQmx backend against nidaqmx's own interpreter seam (no NI driver needed).

As NI's unit tests do (architecture-anchors.md §3): every DAQmx C call goes through an
interpreter; ``nidaqmx.utils._select_interpreter`` is patched to return an autospec of
``BaseInterpreter`` and the calls are checked. ``_select_interpreter`` and
``_base_interpreter`` are private, so this module is pinned to the nidaqmx 1.x line and
skipped on any other major version.
"""

from __future__ import annotations

import math
import time
from importlib.metadata import version
from unittest import mock

import numpy as np
import pytest

nidaqmx = pytest.importorskip("nidaqmx")
if not version("nidaqmx").startswith("1."):
    pytest.skip("interpreter seam checked against nidaqmx 1.x only", allow_module_level=True)

from nidaqmx._base_interpreter import BaseInterpreter  # noqa: E402

from drivers.backends import ni_daq  # noqa: E402
from drivers.contracts import Esc, Sensor  # noqa: E402
from drivers.errors import DeviceError  # noqa: E402

RATE = 25_000.0


@pytest.fixture
def interp(monkeypatch):
    it = mock.create_autospec(BaseInterpreter, instance=True)
    handles = iter(range(1, 100))
    it.create_task.side_effect = lambda name: (f"task{next(handles)}", True)
    it.get_task_attribute_string.return_value = "task"
    it.driver_version = (24, 5, 0)
    monkeypatch.setattr(nidaqmx.utils, "_select_interpreter", lambda *a, **k: it)
    return it


def _config(counter=True):
    return ni_daq.AcquisitionConfig(
        "Dev1", (ni_daq.AiChannel("Dev1/ai0", "bridge_v"), ni_daq.AiChannel("Dev1/ai1", "cur_v"),
                 ni_daq.AiChannel("Dev1/ai2", "volt_v", terminal="DIFF")),
        rate_hz=RATE, counter="Dev1/ctr0" if counter else None)


def test_task_configuration(interp):
    acq = ni_daq.NiAcquisition(_config())
    chans = [c.args[1] for c in interp.create_ai_voltage_chan.call_args_list]
    assert chans == ["Dev1/ai0", "Dev1/ai1", "Dev1/ai2"]
    interp.create_ci_count_edges_chan.assert_called_once()
    assert interp.create_ci_count_edges_chan.call_args.args[1] == "Dev1/ctr0"
    timing = interp.cfg_samp_clk_timing.call_args_list
    assert [c.args[1] for c in timing] == [RATE, RATE]
    assert timing[1].args[2] == "/Dev1/ai/SampleClock"  # counter sampled on the AI clock
    assert timing[0].args[5] == int(RATE * 10)  # 10 s host buffer
    starts = [c.args[0] for c in interp.start_task.call_args_list]
    assert starts == ["task2", "task1"]  # counter first, AI (the clock) last
    acq.close()
    assert {c.args[0] for c in interp.clear_task.call_args_list} == {"task1", "task2"}


def _feed(interp, n, volts, counts):
    """The DAQ buffer holds ``n`` samples until they are read (as a real buffer does)."""
    left = {"task1": n, "task2": n}

    def avail(handle, attr):
        return left.get(handle, 0) if attr == 0x1223 else 3  # avail_samp_per_chan, num_chans

    interp.get_read_attribute_uint32.side_effect = avail

    def read_ai(handle, num, timeout, fill, data):
        data[:] = np.asarray(volts, dtype=float).reshape(3, 1)
        left[handle] -= num
        return data, num

    def read_ci(handle, num, timeout, fill, data):
        data[:] = counts
        left[handle] -= num
        return data, num

    interp.read_analog_f64.side_effect = read_ai
    interp.read_counter_u32_ex.side_effect = read_ci


def test_sensors_calibrate_and_share_one_acquisition(interp):
    hub = ni_daq.NiHub(ni_daq.NiAcquisition(_config()))
    lc = ni_daq.load_cell(hub, "bridge_v", scale_n_per_v=10.0, offset_v=0.1)
    pw = ni_daq.power_sensor(hub, "cur_v", "volt_v", current_mv_per_a=36.60,
                             voltage_mv_per_v=63.69)
    assert isinstance(lc, Sensor) and isinstance(pw, Sensor)
    _feed(interp, 5, [0.6, 0.366, 0.76428], np.arange(5))
    b = lc.read_block()
    assert b.values["thrust_n"] == pytest.approx([5.0] * 5)
    assert np.diff(b.t_s) == pytest.approx([1 / RATE] * 4)
    p = pw.read_block()  # the same 5 samples, fanned out to the second role
    assert p.values["current_a"] == pytest.approx([10.0] * 5)
    assert p.values["voltage_v"] == pytest.approx([12.0] * 5)
    _feed(interp, 0, [0, 0, 0], [])
    assert len(lc.read_block()) == 0
    lc.close()
    pw.close()
    assert interp.clear_task.call_count == 2  # the last role closes the tasks


def test_daq_errors_become_device_errors(interp):
    acq = ni_daq.NiAcquisition(_config(counter=False))
    interp.get_read_attribute_uint32.side_effect = nidaqmx.errors.DaqError(
        "buffer overwritten", -200279)
    with pytest.raises(DeviceError, match="NI-DAQmx read from Dev1"):
        acq.read()
    acq.close()
    interp.create_ai_voltage_chan.side_effect = nidaqmx.errors.DaqError("no such device", -200220)
    with pytest.raises(DeviceError, match="setup of Dev1"):
        ni_daq.NiAcquisition(_config())


def test_bad_terminal_and_empty_config_are_refused():
    with pytest.raises(DeviceError, match="terminal"):
        ni_daq.AcquisitionConfig("Dev1", (ni_daq.AiChannel("Dev1/ai0", "x", terminal="FOO"),))
    with pytest.raises(DeviceError, match="analog input"):
        ni_daq.AcquisitionConfig("Dev1", ())


def test_rpm_from_edges_across_chunks():
    fs, rpm, magnets = RATE, 6000.0, 14
    edge_dt = 60.0 / (rpm * magnets)  # s between edges
    t = np.arange(int(0.1 * fs)) / fs
    counts = np.floor(t / edge_dt).astype(np.uint32)
    est = ni_daq.RpmFromEdges(magnets)
    out = np.concatenate([est.update(t[k:k + 700], counts[k:k + 700])
                          for k in range(0, t.size, 700)])
    settled = out[t > 2 * 60 / rpm]  # after one revolution of edges
    assert settled == pytest.approx(rpm, rel=2 / (fs * 60 / rpm))  # 1 sample in a revolution
    assert np.all(out[: int(edge_dt * fs)] == 0)  # no revolution seen yet: 0
    # the motor stops: no new edges -> 0 rpm after the timeout
    t2 = t[-1] + np.arange(1, int(0.5 * fs)) / fs
    stop = est.update(t2, np.full(t2.size, counts[-1], dtype=np.uint32))
    assert stop[-1] == 0 and stop[0] > 0
    # 32-bit wrap of the counter is not a jump
    est2 = ni_daq.RpmFromEdges(1)
    est2.update(np.array([0.0]), np.array([2**32 - 1], dtype=np.uint32))
    r = est2.update(np.array([0.01, 0.02]), np.array([0, 1], dtype=np.uint32))
    assert r[-1] == pytest.approx(60 / 0.01)


def test_pwm_esc_updates_pulse_on_the_fly_and_stops(interp):
    esc = ni_daq.NiPwmEsc(ni_daq.PwmSettings("Dev1/ctr1", frame_rate_hz=400.0,
                                             host_timeout_s=0.08))
    assert isinstance(esc, Esc)
    (call,) = interp.create_co_pulse_chan_time.call_args_list
    assert call.args[1] == "Dev1/ctr1"
    assert call.args[-2:] == pytest.approx((2.5e-3 - 1e-3, 1e-3))  # low, high at idle
    esc.arm()
    esc.set_pulse_us(1500)
    esc.set_pulse_us(2600)  # clamped to 2000
    writes = [c.args[3:5] for c in interp.write_ctr_time_scalar.call_args_list]
    assert writes[-2] == pytest.approx((1.5e-3, 1.0e-3))
    assert writes[-1] == pytest.approx((2.0e-3, 0.5e-3))
    time.sleep(0.2)  # host silent > 0.08 s: the guard sends idle pulses
    assert interp.write_ctr_time_scalar.call_args.args[3] == pytest.approx(1e-3)
    esc.set_pulse_us(1200)  # commands resume
    assert interp.write_ctr_time_scalar.call_args.args[3] == pytest.approx(1.2e-3)
    esc.close()
    assert interp.write_ctr_time_scalar.call_args.args[3] == pytest.approx(1e-3)
    interp.stop_task.assert_called()
    interp.clear_task.assert_called()
    with pytest.raises(DeviceError, match="closed"):
        esc.set_pulse_us(1500)
    with pytest.raises(DeviceError, match="does not fit"):
        ni_daq.PwmSettings("Dev1/ctr1", frame_rate_hz=1000.0)
    assert math.isfinite(esc.period_s)
