"""nidaq:// rig URLs -> the NI-DAQmx backend, checked against nidaqmx's interpreter seam.

Like tests/drivers/test_backend_ni_daq.py (pinned to nidaqmx 1.x): the factory must put
the load cell and the power sensor on one hardware-timed AI task, the hall counter on the
AI sample clock, and the ESC on a counter output at the rig's frame rate.
"""

from __future__ import annotations

import sys
from importlib.metadata import version
from unittest import mock

import pytest

from bench.rig.rig import load_rig
from drivers.errors import DeviceError
from drivers.factory import open_rig

nidaqmx = pytest.importorskip("nidaqmx")
if not version("nidaqmx").startswith("1."):
    pytest.skip("interpreter seam checked against nidaqmx 1.x only", allow_module_level=True)

from nidaqmx._base_interpreter import BaseInterpreter  # noqa: E402

rigs = sys.modules["rotorbench_tests_factory_rigs"]  # factory_rigs.py, by conftest

DEVICES = {
    "esc": 'url = "nidaq://Dev1/ctr1"',
    "load_cell": 'url = "nidaq://Dev1/ai0"\noptions = { terminal = "DIFF", rate_hz = 20000 }\n'
                 'calibration = { scale_n_per_v = 10.0, offset_v = 0.0 }',
    "power": 'url = "nidaq://Dev1/ai1,ai2"\noptions = { rate_hz = 20000 }\n'
             'calibration = { current_mv_per_a = 36.6, voltage_mv_per_v = 63.69 }',
    "rpm": 'url = "nidaq://Dev1/ctr0"\noptions = { rate_hz = 20000 }\n'
           'calibration = { magnets = 14 }',
}


@pytest.fixture
def interp(monkeypatch):
    it = mock.create_autospec(BaseInterpreter, instance=True)
    handles = iter(range(1, 100))
    it.made = []  # every task handle handed out

    def create_task(name):
        it.made.append(f"task{next(handles)}")
        return it.made[-1], True

    it.create_task.side_effect = create_task
    it.get_task_attribute_string.return_value = "task"
    it.driver_version = (24, 5, 0)
    monkeypatch.setattr(nidaqmx.utils, "_select_interpreter", lambda *a, **k: it)
    return it


def test_one_ai_task_counter_on_its_clock_and_a_pulse_output(tmp_path, interp):
    rig = load_rig(rigs.write(tmp_path, DEVICES))
    r = open_rig(rig)
    ai = [c.args[1] for c in interp.create_ai_voltage_chan.call_args_list]
    assert ai == ["Dev1/ai0", "Dev1/ai1", "Dev1/ai2"]  # one task, every analog input
    assert interp.create_ci_count_edges_chan.call_args.args[1] == "Dev1/ctr0"
    timing = interp.cfg_samp_clk_timing.call_args_list
    assert [c.args[1] for c in timing] == [20000.0, 20000.0]
    assert timing[1].args[2] == "/Dev1/ai/SampleClock"
    co = interp.create_co_pulse_chan_time.call_args
    assert co.args[1] == "Dev1/ctr1"
    low, high = co.args[6], co.args[7]  # low_time / high_time of the 400 Hz frame
    assert (high, high + low) == pytest.approx((1000e-6, 1 / 400.0))
    assert [c.name for c in r.sensors["power"].describe().channels] == ["current_a",
                                                                        "voltage_v"]
    r.close()


@pytest.mark.parametrize(("role", "body", "match"), [
    ("power", 'url = "nidaq://Dev1/ai1,ai2"\noptions = { rate_hz = 10000 }\n'
              'calibration = { current_mv_per_a = 36.6, voltage_mv_per_v = 63.69 }',
     r"options.rate_hz: all channels of Dev1 share one sample clock"),
    ("load_cell", 'url = "nidaq://Dev1/ai0"\noptions = { rate_hz = 20000 }',
     r"\[devices.load_cell\] calibration.scale_n_per_v: missing"),
    ("power", 'url = "nidaq://Dev1/ai1"\noptions = { rate_hz = 20000 }\n'
              'calibration = { current_mv_per_a = 36.6, voltage_mv_per_v = 63.69 }',
     r"\[devices.power\] .*needs 2 analog input"),
    ("esc", 'url = "nidaq://Dev1/ao0"', r"\[devices.esc\] .*counter output"),
])
def test_bad_nidaq_tables_name_the_field(tmp_path, interp, role, body, match):
    with pytest.raises(DeviceError, match=match):
        open_rig(load_rig(rigs.write(tmp_path, {**DEVICES, role: body})))
    # every task made before the refusal is cleared (a leaked Task warns when collected)
    assert sorted(c.args[0] for c in interp.clear_task.call_args_list) == sorted(interp.made)


def test_without_the_ni_driver_the_error_names_the_device(tmp_path, monkeypatch):
    def no_driver(*a, **k):
        raise nidaqmx.errors.DaqNotFoundError("NI-DAQmx driver not installed")

    monkeypatch.setattr(nidaqmx.utils, "_select_interpreter", no_driver)
    with pytest.raises(DeviceError, match=r"\[devices.esc\] 'nidaq://Dev1/ctr1': NI-DAQmx "
                                          r"Dev1/ctr1: DaqNotFoundError"):
        open_rig(load_rig(rigs.write(tmp_path, DEVICES)))
