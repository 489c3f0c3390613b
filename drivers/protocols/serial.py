"""Registry entries of the serial protocols: ``serial://<port>`` with ``protocol = ...``.

``serial:///dev/ttyUSB0``, ``serial://COM3``; one port serves one device (several roles
may share a board or a VESC: same options, one port):

- ``msp``: a flight controller's motor test (the ESC role) or its RAW_IMU (the IMU bench's
  IMU under test); the same openers serve ``msp+tcp://`` (``drivers.protocols.msp_tcp``);
- ``vesc``: a VESC's USB/UART port, the ESC role and the power / rpm roles (GET_VALUES);
- ``loadcell``: a line-printing load-cell board, the sensor roles;
- ``kiss``: KISS / BLHeli_32 ESC telemetry (10-byte frames), the power and rpm roles;
- ``gx3``: a 3DM-GX3-25 streaming Euler angles and rates, the reference IMU.

The host ``sim`` (``serial://sim/msp``, ``serial://sim/loadcell``, ``serial://sim/gx3``...)
starts the wire-level simulated device on a pty (``drivers.wire_sim``), driven by the
rig's simulated world; the path names the protocol when the options do not. The
propulsion stand's peers run with their plant in a child process (``serial_peer``); the
IMU bench's with its world (``drivers.wire_sim.imu_world.start_imu_device``), in a child
process too when every device of the rig is wire-level.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from drivers.contracts import Esc, Sensor
from drivers.device_options import DeviceUrl
from drivers.errors import DeviceError
from drivers.registry import backend, register

PROPULSION_SENSORS = ("load_cell", "power", "rpm")
EXAMPLE = "serial://<port>"


# -- shared ports and peers --------------------------------------------------------------------
def _label(spec: DeviceUrl, protocol: str) -> str:
    """The simulated device's name: ``serial://sim/<label>``."""
    return spec.path.strip("/") or protocol


def serial_peer(ctx: Any, spec: DeviceUrl, kind: str, *args: Any) -> Any:
    """The propulsion peer ``plant_peers.SERIAL_PEERS[kind]`` of ``serial://sim/<label>``,
    started in the world's process (one per label); its ``path`` is the pty to open."""
    wire = ctx.world()
    ctx.wire = wire
    return wire.start_peer(f"serial:{_label(spec, kind)}", kind, args)


def port(ctx: Any, spec: DeviceUrl, protocol: str, default_baud: int,
         start_peer: Callable[[], Any] | None) -> tuple[Any, str]:
    """The serial port of ``spec`` (opened once per port) and its key.

    On the ``sim`` host, ``start_peer()`` gives the simulated device (with its pty path).
    """
    link = backend("serial_link", spec)
    baud = spec.integer("baud", default_baud, lo=50, hi=20_000_000)
    if spec.is_wire_sim:
        label = _label(spec, protocol)
        peer = ctx.shared(("serial-peer", label), start_peer)
        path, key = peer.path, f"sim:{label}"
    else:
        path = (spec.host + spec.path) if spec.host else spec.path
        if not path:
            raise spec.fail("", "expected serial://<port>, e.g. serial:///dev/ttyUSB0 "
                                "or serial://COM3")
        key = path
    if ctx.has_shared(("port", key)):
        used = ctx.shared(("port-protocol", key), lambda: protocol)
        if used != protocol or protocol == "msp":
            raise spec.fail("", f"port {path} is already open for another role "
                                f"({used}); one port serves one device")
        return ctx.shared(("port", key), lambda: None), key
    opened = ctx.shared(("port", key), lambda: link.open_port(path, baud), lambda p: p.close())
    ctx.shared(("port-protocol", key), lambda: protocol)
    return opened, key


# -- MSP: motor-test ESC, IMU under test ---------------------------------------------------------
# The openers below take the link from their transport (this serial port, or msp+tcp://):
# one home for the MSP roles whatever carries the bytes.
CONTROLS = ("rc", "motor_test")  # the MSP ESC's paths; rc unless propellers_off


def open_msp_esc(ctx: Any, spec: DeviceUrl, open_link: Callable[[int], Any]) -> Esc:
    """The FC's motor as the ESC: ``control = "rc"`` (the default with a propeller on: the
    FC armed on its MSP receiver, whose failsafe stops the motor when the host dies) or
    ``"motor_test"`` (MSP_SET_MOTOR, only with ``propellers_off``); ``open_link(motor)``
    gives the connected port."""
    msp_fc = backend("msp_fc", spec)
    motor = spec.integer("motor", 0, lo=0, hi=7)
    version = spec.integer("version", 1, lo=1, hi=2)
    timeout_s = spec.number("timeout_s", msp_fc.DEFAULT_TIMEOUT_S, lo=0.005, hi=5.0)
    link = open_link(motor)
    client = msp_fc.MspClient(link, spec.url, timeout_s=timeout_s, version=version)
    variant, api = client.identify()  # fails here, at open, when nothing answers
    ctx.answers[spec.role] = (f"flight controller {variant}, MSP API "
                              f"{api.api_major}.{api.api_minor}, motor {motor}")
    e = ctx.rig.esc
    propellers_off = spec.flag("propellers_off", False)
    control = spec.text("control", "motor_test" if propellers_off else "rc",
                        choices=CONTROLS)
    if control == "rc":  # a dead host stops the motor: the FC's receiver failsafe
        from drivers.backends.msp_rc_esc import MspRcEsc

        ctx.answers[spec.role] += ", armed on its MSP receiver"
        esc: Esc = MspRcEsc(
            client, motor, min_us=e.min_us, max_us=e.max_us, url=spec.url,
            rate_hz=spec.number("rc_rate_hz", 50.0, lo=20.0, hi=100.0),
            host_timeout_s=spec.number("host_timeout_s", 1.0, lo=0.05, hi=10.0),
            failsafe_delay_s=spec.number("failsafe_delay_s", 1.0, lo=0.1, hi=20.0),
            arm_timeout_s=spec.number("arm_timeout_s", 10.0, lo=0.5, hi=60.0))
    else:
        esc = msp_fc.MspMotorEsc(client, motor, min_us=e.min_us, max_us=e.max_us,
                                 url=spec.url, propellers_off=propellers_off)
    ctx.probes[spec.role] = lambda _t: (client.identify(), ctx.answers[spec.role])[1]
    return esc


def open_msp_imu(ctx: Any, spec: DeviceUrl, open_link: Callable[[], Any]) -> Sensor:
    """RAW_IMU of a flight controller as the IMU under test (``acc_1g``,
    ``gyro_lsb_per_dps``: see msp_fc); ``open_link()`` gives the connected port."""
    msp_fc = backend("msp_fc", spec)
    from drivers.wire_sim.plant_peers import BTFL_ACC_1G

    acc_1g = spec.number("acc_1g", lo=1.0, hi=32768.0) if spec.has("acc_1g") else None
    gyro_lsb = spec.number("gyro_lsb_per_dps", lo=1e-3, hi=1e3) \
        if spec.has("gyro_lsb_per_dps") else None  # None: the firmware's own (msp.imu_si)
    rate_hz = spec.number("rate_hz", ctx.rig.imu.value("rate_hz"), lo=0.1, hi=2000.0)
    timeout_s = spec.number("timeout_s", msp_fc.DEFAULT_TIMEOUT_S, lo=0.005, hi=5.0)
    version = spec.integer("msp_version", 1, lo=1, hi=2)
    link = open_link()
    client = msp_fc.MspClient(link, spec.url, timeout_s=timeout_s, version=version)
    if acc_1g is None and client.identify()[0] == "BTFL":
        acc_1g = BTFL_ACC_1G  # documented default; INAV's 1 g is always 512
    time_scale = getattr(ctx.clock, "time_scale", 1.0)
    return msp_fc.MspImuSensor(msp_fc.MspImu(
        client, rate_hz=rate_hz * time_scale, acc_1g=acc_1g, clock=ctx.clock, url=spec.url,
        attitude=False, gyro_lsb_per_dps=gyro_lsb), rate_hz, port=link,
        peer=ctx.peers.get(spec.role))


@register("serial", "msp", ("esc",), summary="serial devices", example=EXAMPLE,
          default_for=("esc",))
def msp_esc(ctx: Any, spec: DeviceUrl) -> Esc:
    def link(motor: int) -> Any:
        return port(ctx, spec, "msp", 115_200, lambda: serial_peer(ctx, spec, "msp", motor))[0]

    return open_msp_esc(ctx, spec, link)


@register("serial", "msp", ("imu",), summary="serial devices", example=EXAMPLE,
          default_for=("imu",))
def msp_imu(ctx: Any, spec: DeviceUrl) -> Sensor:
    """RAW_IMU of a flight controller on a serial port as the IMU under test."""
    from drivers.codecs import msp
    from drivers.wire_sim.plant_peers import BTFL_ACC_1G

    start: Callable[[], Any] | None = None
    if spec.is_wire_sim:
        variant = spec.text("sim_variant", "BTFL", choices=("BTFL", "INAV"))
        spec.number("time_scale", 1.0, lo=1e-3, hi=1e3)  # the world's clock reads it
        sim_1g = msp.INAV_ACC_1G if variant == "INAV" else spec.integer(
            "sim_acc_1g", BTFL_ACC_1G, lo=1, hi=32767)  # the simulated FC's driver

        def start_peer() -> Any:
            from drivers.wire_sim.imu_world import start_imu_device

            peer = start_imu_device(ctx, f"serial:{_label(spec, 'msp')}", "msp", variant,
                                    round(sim_1g))
            ctx.peers[spec.role] = peer
            return peer

        start = start_peer

    return open_msp_imu(ctx, spec, lambda: port(ctx, spec, "msp", 115_200, start)[0])


# -- VESC over USB/UART ------------------------------------------------------------------------
def _vesc_uart_link(ctx: Any, spec: DeviceUrl) -> tuple[Any, int]:
    """The shared VESC USB/UART port (one link per port) and the motor's pole pairs."""
    vu = backend("vesc_uart", spec)
    pole_pairs = spec.integer("pole_pairs", 7, lo=1, hi=100)
    timeout_s = spec.number("timeout_s", 0.1, lo=0.005, hi=5.0)

    link, key = port(ctx, spec, "vesc", 115_200,
                     lambda: serial_peer(ctx, spec, "vesc", pole_pairs))
    return ctx.shared(("vesc-uart", key),
                      lambda: vu.VescUartLink(link, spec.url, timeout_s)), pole_pairs


@register("serial", "vesc", ("esc",), summary="serial devices", example=EXAMPLE)
def vesc_uart_esc(ctx: Any, spec: DeviceUrl) -> Esc:
    vu = backend("vesc_uart", spec)
    link, _ = _vesc_uart_link(ctx, spec)
    e = ctx.rig.esc
    settings = vu.VescUartSettings(
        e.min_us, e.max_us, spec.number("keepalive_s", 0.1, lo=0.005, hi=0.9),
        spec.number("host_timeout_s", 0.5, lo=0.02, hi=10.0))
    firmware = link.values()  # fails here, at open, when nothing answers
    ctx.answers[spec.role] = f"VESC (USB/UART), controller id {firmware.controller_id}"
    ctx.probes[spec.role] = lambda _t: (link.values(), ctx.answers[spec.role])[1]
    return vu.VescUartEsc(link, settings, spec.url)


@register("serial", "vesc", ("power", "rpm"), summary="serial devices", example=EXAMPLE)
def vesc_uart_telemetry(ctx: Any, spec: DeviceUrl) -> Sensor:
    link, pole_pairs = _vesc_uart_link(ctx, spec)
    rate = spec.number("rate_hz", 100.0, lo=1.0, hi=1000.0)
    stale = spec.number("stale_s", 0.5, lo=0.02, hi=60.0)

    def make() -> Sensor:
        vu = backend("vesc_uart", spec)
        return vu.VescUartTelemetry(link, pole_pairs, rate_hz=rate, clock=ctx.clock,
                                    stale_s=stale, url=spec.url)

    return ctx.shared_sensor(("serial-vesc", spec.host, spec.path), spec, make)


# -- line-printing load-cell boards ------------------------------------------------------------
def _layout(spec: DeviceUrl) -> tuple[Any, str]:
    from drivers.codecs import loadcell_lines as ll

    value = spec.raw("layout", "teststand_v2")
    named = {"teststand_v2": ll.TESTSTAND_V2, "hx711_raw": ll.HX711_RAW}
    if isinstance(value, str):
        if value not in named:
            raise spec.fail("layout", f"{value!r}: expected one of {', '.join(named)} or a "
                                      "table {separator, fields}")
        return named[value], value
    if not isinstance(value, dict):
        raise spec.fail("layout", f"expected a name or a table, got {value!r}")
    try:
        return ll.LineLayout.from_config(value, f"{spec.where} options.layout"), "custom"
    except ll.LayoutError as exc:
        raise DeviceError(str(exc)) from None


@register("serial", "loadcell", PROPULSION_SENSORS, summary="serial devices", example=EXAMPLE,
          default_for=PROPULSION_SENSORS)
def loadcell_board(ctx: Any, spec: DeviceUrl) -> Sensor:
    def make() -> Sensor:
        from drivers.codecs.loadcell_lines import TESTSTAND_V2_BAUD

        layout, name = _layout(spec)
        stale_s = spec.number("stale_s", 0.5, lo=0.02, hi=60.0)
        stamps = spec.text("timestamps", "host", choices=("host", "device"))
        start_text = spec.raw("start", "\n")
        if not isinstance(start_text, str):
            raise spec.fail("start", f"expected a string, got {start_text!r}")
        period_s = spec.number("period_s", 0.004, lo=0.0005, hi=1.0) \
            if spec.is_wire_sim else 0.0

        baud = TESTSTAND_V2_BAUD if name == "teststand_v2" else 115_200
        link, _ = port(ctx, spec, "loadcell", baud,
                       lambda: serial_peer(ctx, spec, "loadcell", layout, period_s))
        lc = backend("loadcell_serial", spec)
        dev = lc.LineLoadCell(link, layout, clock=ctx.clock, stale_s=stale_s, url=spec.url)
        if start_text:
            backend("serial_link", spec).write_all(link, start_text.encode(), spec.url)
        if stamps == "device":  # the board's own t_s column, mapped to the host clock
            from drivers.device_time import DeviceTimeSensor

            return DeviceTimeSensor(dev, "t_s")
        return dev

    return ctx.shared_sensor(("serial", spec.host, spec.path), spec, make)


# -- KISS / BLHeli_32 ESC telemetry -------------------------------------------------------------
@register("serial", "kiss", ("power", "rpm"), summary="serial devices", example=EXAMPLE)
def kiss_telemetry(ctx: Any, spec: DeviceUrl) -> Sensor:
    """The ESC's telemetry wire (10-byte frames) as the power and rpm sources; on the host
    ``sim`` a simulated ESC streams the plant's bus voltage, current and speed."""
    pole_pairs = spec.integer("pole_pairs", 7, lo=1, hi=100)
    stale_s = spec.number("stale_s", 0.5, lo=0.02, hi=60.0)
    period_s = spec.number("period_s", 0.01, lo=0.001, hi=1.0) if spec.is_wire_sim else 0.0
    kt = backend("kiss_telemetry", spec)
    kiss = kt.kiss

    def make() -> Sensor:
        link, _ = port(ctx, spec, "kiss", kiss.BAUD,
                       lambda: serial_peer(ctx, spec, "kiss", pole_pairs, period_s))
        return kt.KissTelemetry(link, pole_pairs, clock=ctx.clock, stale_s=stale_s,
                                url=spec.url)

    return ctx.shared_sensor(("serial-kiss", spec.host, spec.path), spec, make)


# -- 3DM-GX3-25 reference IMU --------------------------------------------------------------------
@register("serial", "gx3", ("reference_imu",), summary="serial devices", example=EXAMPLE,
          default_for=("reference_imu",))
def gx3_reference(ctx: Any, spec: DeviceUrl) -> Sensor:
    """Euler angles and rates (0xCF) streamed by a GX3, stamped from its own timer."""
    gi = backend("gx3_imu", spec)
    from drivers.codecs import gx3

    window_s = spec.number("time_window_s", 5.0, lo=0.1, hi=3600.0)
    stale_s = spec.number("stale_s", 0.2, lo=0.01, hi=60.0)
    open_timeout_s = spec.number("open_timeout_s", 1.0, lo=0.05, hi=30.0)
    start: Callable[[], Any] | None = None
    if spec.is_wire_sim:
        spec.number("time_scale", 1.0, lo=1e-3, hi=1e3)  # the world's clock reads it

        def start_peer() -> Any:
            from drivers.wire_sim.imu_world import start_imu_device

            peer = start_imu_device(ctx, f"serial:{_label(spec, 'gx3')}", "gx3")
            ctx.peers[spec.role] = peer
            return peer

        start = start_peer

    link, _ = port(ctx, spec, "gx3", 115_200, start)
    stale = stale_s * getattr(ctx.clock, "time_scale", 1.0)
    return gi.Gx3Reference(gi.Gx3Imu(link, packet=gx3.EULER_RATES, clock=ctx.clock,
                                     stale_s=stale, open_timeout_s=open_timeout_s,
                                     url=spec.url),
                           window_s=window_s, port=link, peer=ctx.peers.get(spec.role))
