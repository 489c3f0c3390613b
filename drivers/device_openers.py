"""Opening the hardware backends of a rig: ports, buses and DAQ tasks shared per device.

:class:`DeviceOpener` turns checked device URLs (``drivers.device_options``) into backends:

- ``serial://<port>`` (``serial:///dev/ttyUSB0``, ``serial://COM3``): ``protocol = "msp"``
  (flight-controller motor test, the ESC role), ``"vesc"`` (a VESC's USB/UART port: the
  ESC role and the power / rpm roles from GET_VALUES, one port shared) or ``"loadcell"``
  (a line-printing board, sensor roles; several roles may share one board);
- ``can://<python-can interface>/<channel>`` (``can://socketcan/can0``,
  ``can://virtual/bench``): ``protocol = "vesc"`` or ``"dronecan"``; one bus per URL, shared;
  the ESC role commands it, sensor roles read its status broadcasts;
- ``nidaq://<device>/<channels>``: analog inputs and the hall counter of one device on one
  hardware-timed task, the ESC pulse train on a counter output;
- host ``sim`` (``serial://sim/msp``, ``serial://sim/loadcell``, ``can://sim/<channel>``):
  the same backends, talking to ``drivers.wire_sim`` peers on a pty / the virtual bus,
  driven by the simulated rig's plant (``drivers.wire_rig``).

Backends are imported lazily, so a missing optional library (pyserial, python-can,
nidaqmx) is a clear ``DeviceError`` naming the device, not an import failure at start-up.
"""

from __future__ import annotations

import importlib
import itertools
import threading
import time
from collections.abc import Callable
from typing import Any

from drivers.contracts import Clock, Esc, Sensor
from drivers.device_options import DeviceUrl
from drivers.errors import DeviceError
from drivers.role_views import SharedSensor

__all__ = ["DEFAULT_COLUMNS", "DeviceOpener"]

DEFAULT_COLUMNS = {"load_cell": ("thrust_n",), "power": ("current_a", "voltage_v"),
                   "rpm": ("rpm",)}
_LIBS = {"serial_link": "pyserial", "loadcell_serial": "pyserial", "msp_fc": "pyserial",
         "vesc_uart": "pyserial",
         "can_link": "python-can", "vesc": "python-can", "dronecan_esc": "python-can",
         "ni_daq": "nidaqmx", "pi_hexapod": "the standard library"}
_sim_channels = itertools.count()


def backend(name: str, spec: DeviceUrl) -> Any:
    """``drivers.backends.<name>``, or a DeviceError saying which library is missing."""
    try:
        return importlib.import_module(f"drivers.backends.{name}")
    except ImportError as exc:
        lib = _LIBS.get(name, name)
        raise DeviceError(f"{spec.where} url {spec.url!r}: the {spec.scheme}:// backend needs "
                          f"the Python package {lib} ({exc}); install it, e.g. "
                          f"`pip install {lib}`") from None


class DeviceOpener:
    """Opens the devices of one rig; shares ports, buses, boards and DAQ tasks by URL.

    ``close()`` closes what it opened in reverse order (host side first, then the
    simulated peers and their plant).
    """

    def __init__(self, rig: Any, clock: Clock, seed: int | None = None) -> None:
        self.rig = rig
        self.clock = clock
        self.seed = seed
        self.wire = None  # drivers.wire_rig.WireSims once a sim peer is needed
        self._closers: list[Callable[[], None]] = []
        self._ports: dict[str, tuple[str, Any]] = {}  # port key -> (protocol, port)
        self._vesc_links: dict[str, Any] = {}  # port key -> VescUartLink
        self._shared: dict[tuple, tuple[SharedSensor, dict[str, Any]]] = {}
        self._links: dict[tuple[str, str], Any] = {}
        self._sim_links: dict[str, tuple[Any, str]] = {}  # sim channel -> (device link, name)
        self._ni_hubs: dict[str, Any] = {}
        self._ni_plan: dict[str, list[DeviceUrl]] = {}
        self.answers: dict[str, str] = {}  # role -> what the device said when opened
        self._probes: dict[str, Callable[[float], str]] = {}

    # -- bookkeeping ----------------------------------------------------------------------
    def _on_close(self, fn: Callable[[], None]) -> None:
        self._closers.append(fn)

    def close(self) -> None:
        errors = []
        while self._closers:
            fn = self._closers.pop()
            try:
                fn()
            except Exception as exc:  # close everything, report the first problem
                errors.append(exc)
        if self.wire is not None:
            try:
                self.wire.close()
            except Exception as exc:
                errors.append(exc)
            self.wire = None
        if errors:
            raise DeviceError(f"closing the rig's devices: {errors[0]}")

    def _plant(self):
        """The wall-clock plant behind every simulated peer of this rig (built once)."""
        if self.wire is None:
            from drivers.factory import build_sim_rig
            from drivers.wire_rig import WirePlant, WireSims

            self.wire = WireSims(WirePlant(build_sim_rig(self.rig, seed=self.seed)))
        return self.wire.plant

    def _peer(self, key: str, start: Callable[[], Any], stop: Callable[[Any], None]) -> Any:
        self._plant()
        if key not in self.wire.peers:
            peer = start()
            self.wire.add(key, peer, lambda: stop(peer))
        return self.wire.peers[key]

    # -- public ---------------------------------------------------------------------------
    def open_esc(self, spec: DeviceUrl) -> Esc:
        opener = {"serial": self._serial_esc, "can": self._can_esc, "nidaq": self._ni_esc}
        return self._dispatch(spec, opener)

    def open_sensor(self, spec: DeviceUrl) -> Sensor:
        opener = {"serial": self._serial_sensor, "can": self._can_sensor,
                  "nidaq": self._ni_sensor}
        return self._dispatch(spec, opener)

    def probe_esc(self, role: str, timeout_s: float) -> str:
        """What the ESC said: its identification, or a frame heard from it in time."""
        probe = self._probes.get(role)
        if probe is None:
            return self.answers.get(role, "opened")
        return probe(timeout_s)

    def _dispatch(self, spec: DeviceUrl, openers: dict[str, Callable]) -> Any:
        fn = openers.get(spec.scheme)
        if fn is None:
            if spec.scheme == "tcp":
                raise spec.fail("", "tcp:// serves the PI GCS hexapod of the IMU bench; a "
                                    f"propulsion rig's {spec.role} cannot be a hexapod")
            raise spec.fail("", f"unknown device URL scheme {spec.scheme!r}")
        try:
            dev = fn(spec)
            try:
                spec.check_used()
            except DeviceError:
                dev.close()  # opened before the typo was found: do not leak its threads
                raise
            return dev
        except DeviceError as exc:
            msg = str(exc)
            if msg.startswith(spec.rig_path):
                raise
            raise DeviceError(f"{spec.where} {spec.url!r}: {msg}") from None

    # -- serial ---------------------------------------------------------------------------
    def _port(self, spec: DeviceUrl, protocol: str, default_baud: int,
              start_peer: Callable[[], Any] | None) -> tuple[Any, str]:
        link = backend("serial_link", spec)
        baud = spec.integer("baud", default_baud, lo=50, hi=20_000_000)
        if spec.is_wire_sim:
            label = spec.path.strip("/") or protocol
            peer = self._peer(f"serial:{label}", start_peer, lambda p: p.stop())
            path, key = peer.path, f"sim:{label}"
        else:
            path = (spec.host + spec.path) if spec.host else spec.path
            if not path:
                raise spec.fail("", "expected serial://<port>, e.g. serial:///dev/ttyUSB0 "
                                    "or serial://COM3")
            key = path
        if key in self._ports:
            used, port = self._ports[key]
            if used != protocol or protocol == "msp":
                raise spec.fail("", f"port {path} is already open for another role "
                                    f"({used}); one port serves one device")
            return port, key
        port = link.open_port(path, baud)
        self._ports[key] = (protocol, port)
        self._on_close(port.close)
        return port, key

    def _serial_protocol(self, spec: DeviceUrl, default: str) -> str:
        if spec.is_wire_sim and not spec.has("protocol"):
            default = spec.path.strip("/") or default
        return spec.text("protocol", default, choices=("msp", "loadcell", "vesc"))

    def _vesc_uart_link(self, spec: DeviceUrl) -> tuple[Any, int]:
        """The shared VESC USB/UART port (one link per port) and the motor's pole pairs."""
        vu = backend("vesc_uart", spec)
        pole_pairs = spec.integer("pole_pairs", 7, lo=1, hi=100)
        timeout_s = spec.number("timeout_s", 0.1, lo=0.005, hi=5.0)

        def start():
            from drivers.wire_rig import start_vesc_uart

            return start_vesc_uart(self._plant(), pole_pairs)

        port, key = self._port(spec, "vesc", 115_200, start)
        if key not in self._vesc_links:
            self._vesc_links[key] = vu.VescUartLink(port, spec.url, timeout_s)
        return self._vesc_links[key], pole_pairs

    def _serial_esc(self, spec: DeviceUrl) -> Esc:
        protocol = self._serial_protocol(spec, "msp")
        if protocol == "vesc":
            vu = backend("vesc_uart", spec)
            link, _ = self._vesc_uart_link(spec)
            e = self.rig.esc
            settings = vu.VescUartSettings(
                e.min_us, e.max_us, spec.number("keepalive_s", 0.1, lo=0.005, hi=0.9),
                spec.number("host_timeout_s", 0.5, lo=0.02, hi=10.0))
            firmware = link.values()  # fails here, at open, when nothing answers
            self.answers[spec.role] = (f"VESC (USB/UART), controller id "
                                       f"{firmware.controller_id}")
            self._probes[spec.role] = lambda _t: (link.values(), self.answers[spec.role])[1]
            return vu.VescUartEsc(link, settings, spec.url)
        if protocol != "msp":
            raise spec.fail("protocol", f"{protocol!r} cannot drive an ESC; use msp or vesc")
        msp_fc = backend("msp_fc", spec)
        motor = spec.integer("motor", 0, lo=0, hi=7)
        version = spec.integer("version", 1, lo=1, hi=2)
        timeout_s = spec.number("timeout_s", msp_fc.DEFAULT_TIMEOUT_S, lo=0.005, hi=5.0)

        def start():
            from drivers.wire_rig import start_msp_fc

            return start_msp_fc(self._plant(), motor)

        port, _ = self._port(spec, "msp", 115_200, start)
        client = msp_fc.MspClient(port, spec.url, timeout_s=timeout_s, version=version)
        variant, api = client.identify()  # fails here, at open, when nothing answers
        self.answers[spec.role] = (f"flight controller {variant}, MSP API "
                                   f"{api.api_major}.{api.api_minor}, motor {motor}")
        e = self.rig.esc
        esc = msp_fc.MspMotorEsc(client, motor, min_us=e.min_us, max_us=e.max_us, url=spec.url,
                                 propellers_off=spec.flag("propellers_off", False))
        self._probes[spec.role] = lambda _t: (client.identify(), self.answers[spec.role])[1]
        return esc

    def _layout(self, spec: DeviceUrl):
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

    def _shared_sensor(self, key: tuple, spec: DeviceUrl, make: Callable[[], Sensor]) -> Sensor:
        opts = spec.device_options(exclude=("columns",))
        if key in self._shared:
            shared, first = self._shared[key]
            if opts != first:
                diff = sorted(k for k in set(opts) | set(first) if opts.get(k) != first.get(k))
                raise spec.fail(diff[0], "roles sharing one device must give it the same "
                                         f"options (differs from the first role: {diff})")
            for k in opts:
                spec.raw(k)
        else:
            shared = SharedSensor(make())
            self._shared[key] = (shared, opts)
        view = shared.view(spec.role, spec.names("columns", DEFAULT_COLUMNS[spec.role]))
        return view

    def _serial_sensor(self, spec: DeviceUrl) -> Sensor:
        protocol = self._serial_protocol(spec, "loadcell")
        if protocol == "vesc" and spec.role in ("power", "rpm"):
            link, pole_pairs = self._vesc_uart_link(spec)
            rate = spec.number("rate_hz", 100.0, lo=1.0, hi=1000.0)
            stale = spec.number("stale_s", 0.5, lo=0.02, hi=60.0)

            def make_vesc() -> Sensor:
                vu = backend("vesc_uart", spec)
                return vu.VescUartTelemetry(link, pole_pairs, rate_hz=rate, clock=self.clock,
                                            stale_s=stale, url=spec.url)

            return self._shared_sensor(("serial-vesc", spec.host, spec.path), spec, make_vesc)
        if protocol != "loadcell":
            raise spec.fail("protocol", f"{protocol!r} is not a {spec.role} sensor; use "
                                        "loadcell (a line-printing board)")

        def make() -> Sensor:
            from drivers.codecs.loadcell_lines import TESTSTAND_V2_BAUD

            layout, name = self._layout(spec)
            stale_s = spec.number("stale_s", 0.5, lo=0.02, hi=60.0)
            stamps = spec.text("timestamps", "host", choices=("host", "device"))
            start_text = spec.raw("start", "\n")
            if not isinstance(start_text, str):
                raise spec.fail("start", f"expected a string, got {start_text!r}")
            period_s = spec.number("period_s", 0.004, lo=0.0005, hi=1.0) \
                if spec.is_wire_sim else 0.0

            def start():
                from drivers.wire_rig import start_loadcell_board

                return start_loadcell_board(self._plant(), layout, period_s)

            baud = TESTSTAND_V2_BAUD if name == "teststand_v2" else 115_200
            port, _ = self._port(spec, "loadcell", baud, start)
            lc = backend("loadcell_serial", spec)
            dev = lc.LineLoadCell(port, layout, clock=self.clock, stale_s=stale_s, url=spec.url)
            if start_text:
                backend("serial_link", spec).write_all(port, start_text.encode(), spec.url)
            if stamps == "device":  # the board's own t_s column, mapped to the host clock
                from drivers.device_time import DeviceTimeSensor

                return DeviceTimeSensor(dev, "t_s")
            return dev

        key = ("serial", spec.host, spec.path)
        return self._shared_sensor(key, spec, make)

    # -- CAN ------------------------------------------------------------------------------
    def _link(self, spec: DeviceUrl) -> tuple[Any, str]:
        can_link = backend("can_link", spec)
        interface = spec.host
        channel = spec.path[1:] if spec.path.startswith("/") else spec.path
        channel = channel or spec.channel
        if not interface or not channel:
            raise spec.fail("", "expected can://<interface>/<channel>, e.g. "
                                "can://socketcan/can0 or can://virtual/bench")
        if spec.is_wire_sim:
            if channel not in self._sim_links:  # a fresh virtual channel per opened rig
                name = f"rotorbench-sim-{channel}-{next(_sim_channels)}-{id(self):x}"
                sim_bus = can_link.open_bus("virtual", name)
                dev_link = can_link.CanLink(sim_bus, f"sim peers on {name}")
                self._plant()
                self.wire.add(f"can-link:{name}", dev_link,
                              lambda lk=dev_link, b=sim_bus: (lk.close(), b.shutdown()))
                self._sim_links[channel] = (dev_link, name)
            interface, channel = "virtual", self._sim_links[channel][1]
        key = (interface, channel)
        if key not in self._links:
            kwargs = {}
            if spec.has("bitrate"):
                kwargs["bitrate"] = spec.integer("bitrate", lo=10_000, hi=8_000_000)
            bus = can_link.open_bus(interface, channel, **kwargs)
            link = can_link.CanLink(bus, spec.url)
            self._on_close(bus.shutdown)
            self._on_close(link.close)
            self._links[key] = link
        elif spec.has("bitrate"):
            spec.raw("bitrate")
        return self._links[key], channel

    def _can_protocol(self, spec: DeviceUrl) -> str:
        return spec.text("protocol", None, choices=("vesc", "dronecan"))

    def _vesc_ids(self, spec: DeviceUrl) -> tuple[int, int, float]:
        cid = spec.integer("controller_id", None, lo=0, hi=254)
        pole_pairs = spec.integer("pole_pairs", 7, lo=1, hi=100)
        rate = spec.number("status_rate_hz", 50.0, lo=1.0, hi=1000.0)
        return cid, pole_pairs, rate

    def _can_peer(self, spec: DeviceUrl, protocol: str, ident: int, pole_pairs: int,
                  rate_hz: float, channel: str) -> None:
        if not spec.is_wire_sim:
            return
        from drivers import wire_rig

        dev_link = next(lk for lk, name in self._sim_links.values() if name == channel)
        if protocol == "vesc":
            self._peer(f"can:{channel}:vesc:{ident}",
                       lambda: wire_rig.start_vesc(self._plant(), dev_link, ident, pole_pairs,
                                                   rate_hz), lambda p: p.stop())
        else:
            node = 42 + ident
            self._peer(f"can:{channel}:dronecan:{ident}",
                       lambda: wire_rig.start_dronecan_esc(self._plant(), dev_link, node, ident,
                                                           1.0 / rate_hz), lambda p: p.stop())

    def _can_esc(self, spec: DeviceUrl) -> Esc:
        protocol = self._can_protocol(spec)
        link, channel = self._link(spec)
        e = self.rig.esc
        host_timeout = spec.number("host_timeout_s", 0.5, lo=0.02, hi=10.0)
        if protocol == "vesc":
            vesc = backend("vesc", spec)
            cid, pole_pairs, rate = self._vesc_ids(spec)
            keepalive = spec.number("keepalive_s", 0.1, lo=0.005, hi=0.9)
            self._can_peer(spec, protocol, cid, pole_pairs, rate, channel)
            esc = vesc.VescEsc(link, vesc.VescEscSettings(cid, e.min_us, e.max_us, keepalive,
                                                          host_timeout), spec.url)
            self._probes[spec.role] = lambda t: _heard_vesc(link, cid, t)
            return esc
        dce = backend("dronecan_esc", spec)
        index = spec.integer("esc_index", None, lo=0, hi=19)
        node = spec.integer("node_id", 100, lo=1, hi=127)
        period = spec.number("period_s", 0.02, lo=0.002, hi=1.0)
        rate = spec.number("status_rate_hz", 100.0, lo=1.0, hi=1000.0)
        self._can_peer(spec, protocol, index, 0, rate, channel)
        esc = dce.DroneCanEsc(link, dce.DroneCanEscSettings(index, node, e.min_us, e.max_us,
                                                            period, host_timeout), spec.url)
        self._probes[spec.role] = lambda t: _heard_dronecan(link, node, t)
        return esc

    def _can_sensor(self, spec: DeviceUrl) -> Sensor:
        protocol = self._can_protocol(spec)
        link, channel = self._link(spec)
        stale = spec.number("stale_s", 0.5, lo=0.02, hi=60.0)
        if protocol == "vesc":
            cid, pole_pairs, rate = self._vesc_ids(spec)
            self._can_peer(spec, protocol, cid, pole_pairs, rate, channel)

            def make() -> Sensor:
                vesc = backend("vesc", spec)
                return vesc.VescTelemetry(link, cid, pole_pairs, clock=self.clock,
                                          stale_s=stale, rate_hz=rate, url=spec.url)

            return self._shared_sensor(("can", channel, "vesc", cid), spec, make)
        index = spec.integer("esc_index", None, lo=0, hi=19)
        rate = spec.number("status_rate_hz", 100.0, lo=1.0, hi=1000.0)
        self._can_peer(spec, protocol, index, 0, rate, channel)

        def make_dc() -> Sensor:
            dce = backend("dronecan_esc", spec)
            return dce.DroneCanEscTelemetry(link, index, clock=self.clock, stale_s=stale,
                                            url=spec.url)

        return self._shared_sensor(("can", channel, "dronecan", index), spec, make_dc)

    # -- NI-DAQmx -------------------------------------------------------------------------
    def plan_nidaq(self, specs: list[DeviceUrl]) -> None:
        """Group the NI sensor roles by device: one task holds all their analog inputs."""
        for spec in specs:
            if spec.scheme == "nidaq" and spec.role != "esc":
                self._ni_plan.setdefault(_ni_device(spec), []).append(spec)

    def _ni_channels(self, spec: DeviceUrl) -> list[str]:
        text = spec.path.strip("/") or spec.channel
        if not text:
            raise spec.fail("", "expected nidaq://<device>/<channel>, e.g. nidaq://Dev1/ai0")
        names = [c.strip() for c in text.replace(":", ",").split(",") if c.strip()]
        return names

    def _ni_hub(self, device: str, spec: DeviceUrl) -> Any:
        if device in self._ni_hubs:
            return self._ni_hubs[device]
        ni = backend("ni_daq", spec)
        specs = self._ni_plan.get(device) or [spec]
        ai: list[Any] = []
        counter = None
        rates = set()
        for s in specs:
            rates.add(s.number("rate_hz", 25_000.0, lo=1.0, hi=2_000_000.0))
            chans = self._ni_channels(s)
            if s.role == "rpm":
                if len(chans) != 1 or not chans[0].startswith("ctr"):
                    raise s.fail("", "the hall sensor needs one counter, e.g. nidaq://Dev1/ctr0")
                counter = f"{device}/{chans[0]}"
                continue
            want = {"load_cell": 1, "power": 2}[s.role]
            if len(chans) != want or not all(c.startswith("ai") for c in chans):
                raise s.fail("", f"{s.role} needs {want} analog input(s), e.g. "
                                 + ("nidaq://Dev1/ai0" if want == 1 else "nidaq://Dev1/ai1,ai2"))
            term = s.text("terminal", "DEFAULT")
            lo = s.number("min_v", -10.0, lo=-100.0, hi=100.0)
            hi = s.number("max_v", 10.0, lo=-100.0, hi=100.0)
            ai += [ni.AiChannel(f"{device}/{c}", f"{s.role}_{c}", lo, hi, term) for c in chans]
        if len(rates) > 1:
            raise spec.fail("rate_hz", f"all channels of {device} share one sample clock; got "
                                       f"rates {sorted(rates)}")
        if not ai:
            raise spec.fail("", f"{device}: the counter runs on the analog-input sample clock; "
                                "the rig needs an analog input (load cell) on the same device")
        try:
            acq = ni.NiAcquisition(ni.AcquisitionConfig(device, tuple(ai), rates.pop(), counter),
                                   clock=self.clock)
        except DeviceError:
            raise
        except Exception as exc:  # nidaqmx without the NI driver raises its own types
            raise DeviceError(f"NI-DAQmx {device}: {type(exc).__name__}: {exc}") from None
        hub = ni.NiHub(acq)
        self._ni_hubs[device] = hub
        return hub

    def _ni_sensor(self, spec: DeviceUrl) -> Sensor:
        ni = backend("ni_daq", spec)
        device = _ni_device(spec)
        hub = self._ni_hub(device, spec)
        for key in ("rate_hz", "terminal", "min_v", "max_v"):
            spec.raw(key)
        chans = self._ni_channels(spec)
        cal = spec.calibration

        def need(key: str) -> float:
            if key not in cal:
                raise DeviceError(f"{spec.where} calibration.{key}: missing; the NI backend "
                                  "needs it to convert volts")
            return float(cal[key])

        if spec.role == "load_cell":
            return ni.load_cell(hub, f"load_cell_{chans[0]}", need("scale_n_per_v"),
                                float(cal.get("offset_v", 0.0)), url=spec.url)
        if spec.role == "power":
            return ni.power_sensor(hub, f"power_{chans[0]}", f"power_{chans[1]}",
                                   need("current_mv_per_a"), need("voltage_mv_per_v"),
                                   float(cal.get("current_offset_mv", 0.0)), url=spec.url)
        timeout = spec.number("timeout_s", 0.25, lo=0.01, hi=10.0)
        return ni.rpm_sensor(hub, int(need("magnets")), timeout, url=spec.url)

    def _ni_esc(self, spec: DeviceUrl) -> Esc:
        ni = backend("ni_daq", spec)
        chans = self._ni_channels(spec)
        if len(chans) != 1 or not chans[0].startswith("ctr"):
            raise spec.fail("", "the ESC pulse train needs one counter output, e.g. "
                                "nidaq://Dev1/ctr1")
        e = self.rig.esc
        settings = ni.PwmSettings(f"{_ni_device(spec)}/{chans[0]}", e.frame_rate_hz, e.min_us,
                                  e.max_us, e.idle_us,
                                  spec.number("host_timeout_s", 0.5, lo=0.02, hi=10.0),
                                  spec.number("dead_host_s", 0.25, lo=0.01, hi=10.0))
        try:
            esc = ni.NiPwmEsc(settings, url=spec.url)
        except DeviceError:
            raise
        except Exception as exc:  # nidaqmx without the NI driver raises its own types
            raise DeviceError(f"NI-DAQmx {settings.counter}: {type(exc).__name__}: {exc}") \
                from None
        self.answers[spec.role] = f"counter output {settings.counter} running"
        return esc


def _ni_device(spec: DeviceUrl) -> str:
    from urllib.parse import urlsplit

    device = urlsplit(spec.url).netloc
    if not device:
        raise spec.fail("", "expected nidaq://<device>/<channel>, e.g. nidaq://Dev1/ai0")
    return device


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
