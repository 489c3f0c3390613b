"""KISS / BLHeli_32 telemetry backend: transcript in, SI blocks out; on the simulated rig."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("serial")

from bench.cli import main
from bench.rig.rig import load_rig
from drivers.backends.kiss_telemetry import KissTelemetry
from drivers.backends.serial_link import open_port
from drivers.codecs import kiss
from drivers.codecs.transcript import parse_hex_dump
from drivers.contracts import Sensor
from drivers.errors import DeviceError
from drivers.factory import open_rig
from drivers.wire_sim.pty_sim import PtyStream

ep = sys.modules["rotorbench_tests_expected_protocol"]
RIGS = Path(__file__).resolve().parents[2] / "bench" / "data" / "rigs"
T = Path(__file__).resolve().parents[2] / "fixtures" / "transcripts" / "kiss"


def test_transcript_to_si_rows_and_the_host_writes_nothing():
    frames = parse_hex_dump((T / "noisy.hex").read_text())
    port = ep.ScriptedPort([(b"", frames)])  # the ESC streams; nothing is asked
    dev = KissTelemetry(port, pole_pairs=7, stale_s=0.5)
    assert isinstance(dev, Sensor)
    assert ep.wait_for(lambda: port.idle_reads > 0)  # all read, decoded and stored
    assert dev.decoder.stats.bytes_in == len(frames)
    b = dev.read_block()
    dev.close()
    assert len(b) == 2  # frame 1 twice; the damaged frame 2 is dropped
    assert b.values["voltage_v"].tolist() == [12.34, 12.34]
    assert b.values["current_a"].tolist() == [5.67, 5.67]
    assert b.values["rpm"] == pytest.approx([98_700 / 7] * 2)
    assert b.values["temperature_c"].tolist() == [36.0, 36.0]
    assert b.values["consumption_mah"].tolist() == [89.0, 89.0]
    assert dev.decoder.stats.bad_checksums == 1
    assert port.written == b"" and port.done()


def test_silence_is_an_error_naming_the_crc_count():
    port = ep.ScriptedPort([(b"", b"\x01" * 10)])  # ten bytes that are not a frame
    dev = KissTelemetry(port, pole_pairs=7, stale_s=0.05, url="serial://esc")
    assert ep.wait_for(lambda: dev.decoder.stats.bytes_in == 10)
    with pytest.raises(DeviceError, match=r"serial://esc: no telemetry frame .*\(1 CRC errors"):
        ep.wait_for(lambda: dev.read_block() is None)  # until the reader finds it silent
    dev.close()
    with pytest.raises(DeviceError, match="pole_pairs"):
        KissTelemetry(ep.ScriptedPort([]), pole_pairs=0)


def test_a_streaming_pty_device_speaks_the_frames_to_the_backend():
    frame = kiss.encode(kiss.Telemetry(25.0, 11.1, 4.2, 12.0, 6000.0 * 7))
    esc = PtyStream(lambda: frame, period_s=0.005).start()
    port = open_port(esc.path, kiss.BAUD)
    dev = KissTelemetry(port, pole_pairs=7, stale_s=0.5)
    try:
        assert ep.wait_for(lambda: dev.decoder.stats.messages >= 5)
        b = dev.read_block()
        assert b.values["voltage_v"][-1] == pytest.approx(11.1)
        assert b.values["current_a"][-1] == pytest.approx(4.2)
        assert b.values["rpm"][-1] == pytest.approx(6000.0)  # 42 000 eRPM / 7
        assert b.values["consumption_mah"][-1] == 12.0
        assert dev.decoder.stats.bad_checksums == 0
    finally:
        dev.close()
        port.close()
        esc.stop()


def test_sim_kiss_rig_reports_the_plant():
    with open_rig(load_rig(RIGS / "sim-kiss.toml")) as r:
        assert [c.name for c in r.sensors["power"].describe().channels] == ["current_a",
                                                                           "voltage_v"]
        assert [c.name for c in r.sensors["rpm"].describe().channels] == ["rpm"]
        r.esc.arm()
        rows = {"power": [], "rpm": []}
        for _ in range(50):
            r.esc.set_pulse_us(1500.0)
            r.clock.sleep(0.02)
            for role in rows:
                rows[role].append(r.sensors[role].read_block())
        truth = r.truth()
        rpm = np.concatenate([b.values["rpm"] for b in rows["rpm"]])
        amps = np.concatenate([b.values["current_a"] for b in rows["power"]])
        assert rpm.size > 40  # 100 frames/s
        assert rpm[-3:].mean() == pytest.approx(truth.rpm, rel=0.02)
        assert amps[-3:].mean() == pytest.approx(truth.current_bus_a, abs=0.05)  # 0.01 A LSB
    assert not r.wire.peers  # the simulated ESC stopped with the rig


def test_step_on_the_sim_kiss_rig(tmp_path, capsys):
    """A short step through the CLI: the run records KISS speed and power, and fits."""
    out = tmp_path / "runs"
    rig = RIGS / "sim-kiss.toml"
    code = main(["step", "--rig", str(rig), "--repeats", "2", "--hold", "0.4",
                 "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "success" in captured.out
    (run,) = [p for p in out.iterdir() if p.is_dir() and p.name.endswith("step1")]
    meta = json.loads((run / "run.json").read_text())
    assert meta["rig"]["devices"]["rpm"]["url"] == "serial://sim/kiss"
    assert main(["fit", str(run), "--json"]) == 0
    fit = json.loads(capsys.readouterr().out)
    assert min(fit["repeats_up"], fit["repeats_down"]) >= 1
