"""The bench on the wire-level simulated rigs: same step results, safe ends on disconnects.

``bench/data/rigs/sim-serial.toml`` (MSP motor test + line-printing load-cell board on ptys)
and ``sim-can.toml`` (VESC on python-can's virtual bus + the board) run the real backends
against simulated devices driven by the plant of ``sim.toml``, in real time, in a process
of their own. These tests run ``rotorbench step`` / ``fit`` / ``check`` through the CLI and
the runner through ``bench.plan_runner.session``; each wire run takes a few seconds of wall
time.
"""

from __future__ import annotations

import json
import math
import re
import time

import pytest

from analysis.run_record import read_run
from bench.cli import main
from bench.plan_runner.runner import RunOptions
from bench.plan_runner.session import run_sequence
from bench.plans.sequences import Arm, Disarm, Sequence, Tare, ThrottleStep
from bench.rig.rig import default_rig_path, load_rig
from drivers.errors import DeviceError
from drivers.factory import open_rig

pytest.importorskip("serial")
pytest.importorskip("can")

pytestmark = pytest.mark.slow(wall_s=35)  # wire-level rigs in real time: started first

RIGS = default_rig_path().parent


def _fit(run_root, capsys) -> dict:
    (run_dir,) = [p for p in run_root.iterdir() if p.is_dir() and p.name.endswith("step1")]
    assert main(["fit", str(run_dir), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_step_fits_agree_on_sim_serial_and_can_rigs(tmp_path, capsys):
    fits = {}
    for name in ("sim", "sim-serial", "sim-can", "sim-vesc-uart"):
        out = tmp_path / name
        code = main(["step", "--rig", str(RIGS / f"{name}.toml"), "--repeats", "3",
                     "--hold", "0.4", "--out", str(out)])
        captured = capsys.readouterr()
        assert code == 0, captured.err
        assert "success" in captured.out
        fits[name] = _fit(out, capsys)
    ref = fits["sim"]
    for name in ("sim-serial", "sim-can", "sim-vesc-uart"):
        fit = fits[name]
        assert ref["repeats_up"] == ref["repeats_down"] == 3
        # an edge with a gap in its rows (a host stall) is left out by the fit
        assert min(fit["repeats_up"], fit["repeats_down"]) >= 2, fit["edges"]
        # Time constants: the plant is the same; the wire only delays and samples. A 4 ms
        # boxcar (the board's line period) widens an edge by ~1 ms rms, which moves a
        # 30 ms first-order fit by far less than 10 %; 3 ms floor for scheduling noise.
        for key in ("tau_up_ms", "tau_down_ms"):
            assert abs(fit[key] - ref[key]) <= max(3.0, 0.10 * ref[key]), (name, key, fit, ref)
        # Latency: the wire adds 0..2.5 ms waiting for the ESC frame (commands arrive at
        # any phase; the sim runner sends on frame edges), ~2 ms from the board's 4 ms
        # averaging, plus transport and thread wake-ups (allow 5 ms on a loaded host).
        extra = fit["latency_ms"] - ref["latency_ms"]
        assert -1.0 <= extra <= 2.5 + 4.0 + 5.0, (name, extra)
        assert fit["gain"] == pytest.approx(ref["gain"], rel=0.03)


# -- disconnects mid-run ---------------------------------------------------------------------
class _Watched:
    """A sensor or ESC wrapper that notes when it first raised DeviceError (detection)."""

    def __init__(self, dev, log: dict, role: str) -> None:
        self._dev, self._log, self._role = dev, log, role

    def __getattr__(self, name):
        attr = getattr(self._dev, name)
        if name not in ("read_block", "set_pulse_us"):
            return attr

        def call(*a, **k):
            try:
                return attr(*a, **k)
            except DeviceError:
                self._log.setdefault("detected", time.monotonic())
                self._log.setdefault("role", self._role)
                raise
        return call


def _run_with_fault(tmp_path, rig_name: str, fault, kill_at_s: float = 1.2):
    """Hold 1500 us and apply ``fault(open_rig)`` at ``kill_at_s`` of the run."""
    rig = load_rig(RIGS / f"{rig_name}.toml")
    seq = Sequence("hold", (Arm(0.2), Tare(0.3), ThrottleStep(1500.0, 3.0), Disarm()))
    log: dict = {}
    opened = []

    def opener(cfg, seed=None):
        r = open_rig(cfg, seed=seed)
        opened.append(r)
        close = r.close

        def close_when_idle():  # keep the peers alive until the plant idles (or 2 s)
            deadline = time.monotonic() + 2.0
            while r.wire.plant.idle_since() is None and time.monotonic() < deadline:
                time.sleep(0.02)
            log["idle"] = r.wire.plant.idle_since()
            close()

        r.close = close_when_idle
        r.sensors = {k: _Watched(s, log, k) for k, s in r.sensors.items()}
        r.esc = _Watched(r.esc, log, "esc")
        return r

    def on_progress(t, _total, _seg):
        if t >= kill_at_s and "fault" not in log:
            log["fault"] = time.monotonic()
            fault(opened[0])

    with pytest.raises(DeviceError):
        run_sequence(rig, seq, tmp_path, opener, options=RunOptions(tick_s=0.02),
                     on_progress=on_progress)
    (run_dir,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    return opened[0], log, read_run(run_dir)


def _data_kept_until_fault(record, kill_at_s: float) -> None:
    assert "safe_stop" in set(record.events["kind"])
    t = record.column("t_s")
    thrust = record.column("thrust_n")
    assert t.size > 100
    assert t[-1] >= kill_at_s - 0.05  # the rows up to the fault are on disk
    assert thrust[t > 1.0].mean() > 1.0  # the motor was running at 1500 us


def _idle_after_detection(log) -> float:
    assert log["idle"] is not None, "the ESC never went to idle"
    return log["idle"] - log["detected"]


def test_load_cell_board_unplugged_ends_the_run_with_esc_idle(tmp_path):
    # sim-serial: the board's pty closes (USB unplugged); the ESC (MSP) is still there
    _, log, rec = _run_with_fault(
        tmp_path, "sim-serial", lambda r: r.wire.peers["serial:loadcell"].stop())
    assert rec.meta["status"] == "fail"
    assert "serial://sim/loadcell" in rec.meta["reason"]
    assert log["role"] in ("load_cell", "power", "rpm")
    _data_kept_until_fault(rec, 1.2)
    assert 0.0 <= _idle_after_detection(log) < 0.1


def test_silent_board_is_detected_by_staleness_and_the_esc_idles(tmp_path):
    # sim-can: the board stops printing; its stale_s = 0.25 s ends the run; the VESC
    # gets SET_CURRENT 0 on the bus
    _, log, rec = _run_with_fault(
        tmp_path, "sim-can", lambda r: r.wire.peers["serial:loadcell"].port.disconnect())
    # found by the board's reader (a read past stale_s found no line) or, first, by the
    # runner's own staleness limit on the load cell's samples (the same 0.25 s)
    reason = rec.meta["reason"]
    assert "no data line" in reason or "load_cell: no samples for" in reason, reason
    runner = re.search(r"no samples for ([\d.]+) s", reason)
    detected_after = float(runner[1]) if runner else log["detected"] - log["fault"]
    assert 0.2 <= detected_after < 0.25 + 0.5
    _data_kept_until_fault(rec, 1.2)
    log.setdefault("detected", log["fault"] + detected_after)
    # the runner's finding is read from its reason, to 0.01 s: idle may seem up to 5 ms early
    assert -0.005 <= _idle_after_detection(log) < 0.1


def test_vesc_gone_from_the_bus_ends_the_run_and_its_timeout_stops_the_motor(tmp_path):
    def unplug(r):
        (key,) = [k for k in r.wire.peers if k.startswith("can:") and k.endswith(":vesc:1")]
        r.wire.peers[key].disconnect()

    _, log, rec = _run_with_fault(tmp_path, "sim-can", unplug)
    assert "silent" in rec.meta["reason"] and log["role"] in ("power", "rpm")
    assert "safe_stop" in set(rec.events["kind"])
    _data_kept_until_fault(rec, 1.2)
    # The host cannot reach a VESC that is gone: the VESC's own 1 s command timeout
    # (protocols.md §3.2) releases the motor, counted from the last command it heard.
    assert log["idle"] is not None and log["idle"] - log["fault"] < 1.0 + 0.2


def test_flight_controller_silent_is_recorded(tmp_path):
    _, log, rec = _run_with_fault(
        tmp_path, "sim-serial", lambda r: r.wire.peers["serial:msp"].port.disconnect())
    assert log["role"] == "esc"
    assert "no reply to MSP command" in rec.meta["reason"]
    _data_kept_until_fault(rec, 1.2)
    assert rec.meta.get("safe_stop_errors") is not None


# -- rotorbench check ------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["sim", "sim-serial", "sim-can", "sim-vesc-uart"])
def test_check_reports_every_device_of_the_sim_rigs(name, capsys):
    code = main(["check", "--rig", str(RIGS / f"{name}.toml"), "--json", "--timeout", "5"])
    out = capsys.readouterr().out
    assert code == 0, out
    lines = [json.loads(x) for x in out.splitlines()]
    assert [x["role"] for x in lines] == ["esc", "load_cell", "power", "rpm"]
    assert all(x["ok"] for x in lines)
    rate = float(lines[1]["detail"].split(" samples/s")[0])
    assert math.isfinite(rate) and rate > 50


def test_check_exits_2_naming_the_device_that_does_not_answer(tmp_path, capsys):
    text = (RIGS / "sim-serial.toml").read_text()
    text = text.replace('url = "serial://sim/msp"', 'url = "serial:///dev/rotorbench-no-such-port"')
    rig_file = tmp_path / "rig.toml"
    rig_file.write_text(text.replace('file = "sim.thrust_map.csv"', 'file = "none.csv"'))
    assert main(["check", "--rig", str(rig_file), "--timeout", "5"]) == 2
    out = capsys.readouterr().out
    first, *rest = out.splitlines()
    assert first.startswith("esc") and "FAIL" in first and "no-such-port" in first
    assert len(rest) == 3 and all(" ok " in line for line in rest), out


# -- rotorbench devices ----------------------------------------------------------------------
def test_devices_lists_ports_and_can_channels_as_rig_urls(monkeypatch, capsys):
    import drivers.discovery as disc

    monkeypatch.setattr(disc, "serial_ports", lambda: (
        [disc.SerialPort("/dev/ttyACM0", "STM32 Virtual ComPort (Betaflight)", "USB 0483:5740")],
        ""))
    monkeypatch.setattr(disc, "can_configs", lambda timeout_s=5.0: (
        [disc.CanConfig("socketcan", "can0")], ""))
    assert main(["devices"]) == 0
    out = capsys.readouterr().out
    assert "serial:///dev/ttyACM0" in out and "Betaflight" in out
    assert "can://socketcan/can0" in out
    assert main(["devices", "--json"]) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert [x["url"] for x in lines] == ["serial:///dev/ttyACM0", "can://socketcan/can0"]


def test_devices_on_this_host_never_fails(capsys):
    assert main(["devices", "--no-can", "--json"]) == 0
    for line in capsys.readouterr().out.splitlines():
        assert json.loads(line)["url"].startswith("serial://")
