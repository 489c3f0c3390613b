"""Registry entries of a flight controller reached over TCP: ``msp+tcp://host[:5761]``.

The same MSP roles as ``serial://`` with ``protocol = "msp"`` (the motor test as the ESC,
RAW_IMU as the IMU bench's IMU under test), opened by the same openers over a TCP
connection: ser2net or a WiFi-MSP bridge in front of a real FC, or Betaflight's SITL
(UART n on TCP 5760 + n; the default port 5761 is its MSP port). The connection carries
only whole MSP request frames (``drivers.backends.msp_tcp``). One connection per FC:
Betaflight serves one client per port, so a second role on the same host and port is
refused here rather than dropped by the firmware. With ``launch = "betaflight-sitl"`` the
bench starts the SITL itself for the run (``drivers.protocols.betaflight_sitl``).
"""

from __future__ import annotations

from typing import Any

from drivers.contracts import Esc, Sensor
from drivers.device_options import DeviceUrl
from drivers.protocols.serial import open_msp_esc, open_msp_imu
from drivers.registry import backend, register

SCHEME = "msp+tcp"
EXAMPLE = "msp+tcp://<host>[:5761]"


def _link(ctx: Any, spec: DeviceUrl, connected: Any = None) -> Any:
    """The connected MSP port of ``spec`` (one per host and port), closed with the rig;
    ``connected``: a port already connected to it (the launched SITL's)."""
    mt = backend("msp_tcp", spec)
    if not spec.host:
        raise spec.fail("", f"expected {EXAMPLE}, e.g. msp+tcp://127.0.0.1:5761")
    if spec.path.strip("/"):
        raise spec.fail("", f"expected {EXAMPLE} without a path")
    port = spec.port or mt.DEFAULT_PORT
    key = ("msp+tcp", spec.host, port)
    if ctx.has_shared(key):
        raise spec.fail("", f"{spec.host}:{port} is already open for another role; the "
                            "flight controller serves one MSP client per port")
    return ctx.shared(key, lambda: connected or mt.open_port(
        spec.host, port, spec.url, connect_timeout_s=ctx.open_timeout_s), lambda p: p.close())


@register(SCHEME, None, ("esc",), summary="a flight controller's MSP over TCP",
          example=EXAMPLE)
def msp_tcp_esc(ctx: Any, spec: DeviceUrl) -> Esc:
    if spec.has("launch"):  # the bench starts the firmware (Betaflight SITL) itself
        from drivers.protocols.betaflight_sitl import open_sitl_esc

        return open_sitl_esc(ctx, spec, lambda port: _link(ctx, spec, port))
    return open_msp_esc(ctx, spec, lambda _motor: _link(ctx, spec))


@register(SCHEME, None, ("imu",), summary="a flight controller's MSP over TCP",
          example=EXAMPLE)
def msp_tcp_imu(ctx: Any, spec: DeviceUrl) -> Sensor:
    if spec.has("launch"):  # the firmware as the IMU under test, fed the hexapod's world
        from drivers.protocols.betaflight_sitl import open_sitl_imu

        return open_sitl_imu(ctx, spec, lambda port: _link(ctx, spec, port))
    return open_msp_imu(ctx, spec, lambda: _link(ctx, spec))
