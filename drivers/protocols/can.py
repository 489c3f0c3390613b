"""Registry entries of the CAN protocols: ``can://<python-can interface>/<channel>``.

``can://socketcan/can0``, ``can://virtual/bench``; ``protocol = "vesc"`` or ``"dronecan"``.
One bus per URL, shared by every role on it: the ESC role commands the controller, the
sensor roles read its status broadcasts. The host ``sim`` (``can://sim/<channel>``) puts
the simulated VESC / DroneCAN ESC (``drivers.wire_sim``) on a fresh python-can virtual
channel, driven by the rig's wire plant: the nodes run with the plant in its process, the
channel's far end joined to them by a loopback socket (``drivers.wire_sim.can_socket``).
"""

from __future__ import annotations

import itertools
import threading
import time
from collections.abc import Callable
from typing import Any

from drivers.contracts import Esc, Sensor
from drivers.device_options import DeviceUrl
from drivers.errors import DeviceError
from drivers.registry import backend, register

EXAMPLE = "can://<interface>/<channel>"
SUMMARY = "CAN bus ESCs"
_sim_channels = itertools.count()


def _bus(ctx: Any, spec: DeviceUrl) -> tuple[Any, str, Any]:
    """The shared ``CanLink`` of the URL's bus, its channel name and, on the ``sim`` host,
    the simulated peers' side of the channel (else None)."""
    can_link = backend("can_link", spec)
    interface = spec.host
    channel = spec.path[1:] if spec.path.startswith("/") else spec.path
    channel = channel or spec.channel
    if not interface or not channel:
        raise spec.fail("", "expected can://<interface>/<channel>, e.g. "
                            "can://socketcan/can0 or can://virtual/bench")
    if spec.is_wire_sim:  # a fresh virtual channel per opened rig
        def sim_bus() -> tuple[Any, str]:
            name = f"rotorbench-sim-{channel}-{next(_sim_channels)}-{id(ctx):x}"
            bus = can_link.open_bus("virtual", name)
            dev_link = can_link.CanLink(bus, f"sim peers on {name}")
            wire = ctx.world()
            ctx.wire = wire
            wire.add(f"can-end:{name}", dev_link,
                     lambda lk=dev_link, b=bus: (lk.close(), b.shutdown()))
            wire.bridge_can(name, dev_link)  # to the nodes in the world's process
            return dev_link, name

        peer_link, channel = ctx.shared(("can-sim", channel), sim_bus)
        interface = "virtual"
    else:
        peer_link = None
    if not ctx.has_shared(("can", interface, channel)):
        kwargs = {}
        if spec.has("bitrate"):
            kwargs["bitrate"] = spec.integer("bitrate", lo=10_000, hi=8_000_000)

        def make() -> Any:
            bus = can_link.open_bus(interface, channel, **kwargs)
            ctx.on_close(bus.shutdown)
            return can_link.CanLink(bus, spec.url)

        ctx.shared(("can", interface, channel), make, lambda lk: lk.close())
    elif spec.has("bitrate"):
        spec.raw("bitrate")
    return ctx.shared(("can", interface, channel), lambda: None), channel, peer_link


def _vesc_ids(spec: DeviceUrl) -> tuple[int, int, float]:
    cid = spec.integer("controller_id", None, lo=0, hi=254)
    pole_pairs = spec.integer("pole_pairs", 7, lo=1, hi=100)
    rate = spec.number("status_rate_hz", 50.0, lo=1.0, hi=1000.0)
    return cid, pole_pairs, rate


def _vesc_peer(ctx: Any, link: Any, channel: str, cid: int, pole_pairs: int,
               rate: float) -> None:
    if link is not None:
        ctx.wire.start_can_peer(f"can:{channel}:vesc:{cid}", "vesc", channel,
                                (cid, pole_pairs, rate))


def _dronecan_peer(ctx: Any, link: Any, channel: str, index: int, rate: float) -> None:
    if link is not None:
        ctx.wire.start_can_peer(f"can:{channel}:dronecan:{index}", "dronecan", channel,
                                (42 + index, index, 1.0 / rate))


@register("can", "vesc", ("esc",), summary=SUMMARY, example=EXAMPLE)
def vesc_esc(ctx: Any, spec: DeviceUrl) -> Esc:
    link, channel, peer_link = _bus(ctx, spec)
    e = ctx.rig.esc
    host_timeout = spec.number("host_timeout_s", 0.5, lo=0.02, hi=10.0)
    vesc = backend("vesc", spec)
    cid, pole_pairs, rate = _vesc_ids(spec)
    keepalive = spec.number("keepalive_s", 0.1, lo=0.005, hi=0.9)
    _vesc_peer(ctx, peer_link, channel, cid, pole_pairs, rate)
    esc = vesc.VescEsc(link, vesc.VescEscSettings(cid, e.min_us, e.max_us, keepalive,
                                                  host_timeout), spec.url)
    ctx.probes[spec.role] = lambda t: _heard_vesc(link, cid, t)
    return esc


@register("can", "vesc", ("load_cell", "power", "rpm"), summary=SUMMARY, example=EXAMPLE)
def vesc_telemetry(ctx: Any, spec: DeviceUrl) -> Sensor:
    link, channel, peer_link = _bus(ctx, spec)
    stale = spec.number("stale_s", 0.5, lo=0.02, hi=60.0)
    cid, pole_pairs, rate = _vesc_ids(spec)
    _vesc_peer(ctx, peer_link, channel, cid, pole_pairs, rate)

    def make() -> Sensor:
        vesc = backend("vesc", spec)
        return vesc.VescTelemetry(link, cid, pole_pairs, clock=ctx.clock, stale_s=stale,
                                  rate_hz=rate, url=spec.url)

    return ctx.shared_sensor(("can", channel, "vesc", cid), spec, make)


@register("can", "dronecan", ("esc",), summary=SUMMARY, example=EXAMPLE)
def dronecan_esc(ctx: Any, spec: DeviceUrl) -> Esc:
    link, channel, peer_link = _bus(ctx, spec)
    e = ctx.rig.esc
    host_timeout = spec.number("host_timeout_s", 0.5, lo=0.02, hi=10.0)
    dce = backend("dronecan_esc", spec)
    index = spec.integer("esc_index", None, lo=0, hi=19)
    node = spec.integer("node_id", 100, lo=1, hi=127)
    period = spec.number("period_s", 0.02, lo=0.002, hi=1.0)
    rate = spec.number("status_rate_hz", 100.0, lo=1.0, hi=1000.0)
    _dronecan_peer(ctx, peer_link, channel, index, rate)
    esc = dce.DroneCanEsc(link, dce.DroneCanEscSettings(index, node, e.min_us, e.max_us,
                                                        period, host_timeout), spec.url)
    ctx.probes[spec.role] = lambda t: _heard_dronecan(link, node, t)
    return esc


@register("can", "dronecan", ("load_cell", "power", "rpm"), summary=SUMMARY, example=EXAMPLE)
def dronecan_telemetry(ctx: Any, spec: DeviceUrl) -> Sensor:
    link, channel, peer_link = _bus(ctx, spec)
    stale = spec.number("stale_s", 0.5, lo=0.02, hi=60.0)
    index = spec.integer("esc_index", None, lo=0, hi=19)
    rate = spec.number("status_rate_hz", 100.0, lo=1.0, hi=1000.0)
    _dronecan_peer(ctx, peer_link, channel, index, rate)

    def make() -> Sensor:
        dce = backend("dronecan_esc", spec)
        return dce.DroneCanEscTelemetry(link, index, clock=ctx.clock, stale_s=stale,
                                        url=spec.url)

    return ctx.shared_sensor(("can", channel, "dronecan", index), spec, make)


# -- signs of life (rotorbench check) -----------------------------------------------------------
def _heard(link: Any, match: Callable[[Any], bool], timeout_s: float, what: str) -> str:
    heard = threading.Event()

    def on_frame(frame: Any) -> None:
        if match(frame):
            heard.set()

    link.subscribe(on_frame)
    t0 = time.monotonic()
    try:
        if not heard.wait(timeout_s):
            raise DeviceError(f"nothing heard from {what} within {timeout_s:g} s")
    finally:
        link.unsubscribe(on_frame)
    return f"{what} answers ({(time.monotonic() - t0) * 1e3:.0f} ms)"


def _heard_vesc(link: Any, cid: int, timeout_s: float) -> str:
    from drivers.codecs import vesc_can as vc

    dec = vc.VescDecoder(controller_ids={cid})
    return _heard(link, lambda f: bool(dec.feed(f)), timeout_s,
                  f"VESC {cid} (status broadcasts)")


def _heard_dronecan(link: Any, host_node: int, timeout_s: float) -> str:
    from drivers.codecs import dronecan as dc

    def other_node(frame: Any) -> bool:
        mid = dc.MessageId.from_int(frame.arbitration_id) if frame.is_extended_id else None
        return mid is not None and mid.source_node_id != host_node

    return _heard(link, other_node, timeout_s, "a DroneCAN node")
