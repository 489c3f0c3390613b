"""IMU-bench rig URLs -> devices: the hexapod, the IMU under test, the reference IMU.

``open_imu_rig(rig)`` takes a validated IMU rig config (``bench.imu_rig.ImuRigConfig``,
duck-typed so ``drivers`` does not import ``bench``). ``sim://`` devices come from one
seeded :class:`~drivers.sim.imu_rig.SimImuRig`. Real backends:

* hexapod ``tcp://host[:port]``: a PI GCS controller
  (:class:`drivers.backends.pi_hexapod.PiHexapod`, limits and log rate from the rig file);
* IMU under test ``serial://<port>`` with ``protocol = "msp"``: a flight controller's
  RAW_IMU (:class:`drivers.imu_wire.MspImuSensor`; ``acc_1g`` option, see there);
* reference IMU ``serial://<port>`` with ``protocol = "gx3"``: a 3DM-GX3-25 streaming
  Euler angles and rates (:class:`drivers.imu_wire.Gx3Reference`).

The host ``sim`` starts the wire-level simulated device and connects the real backend to
it: ``tcp://sim[:port]`` the simulated PI controller on loopback, ``serial://sim/<name>``
an MSP flight controller or a GX3 on a pty, all driven by the one simulated bench the
``sim://`` devices read. With a serial peer the bench runs on the wall clock
(:class:`drivers.imu_wire.PacedClock`, option ``time_scale``); otherwise on its fast
simulated clock. A rig is either all simulated or all real: a real IMU cannot see a
simulated hexapod's motion, nor a simulated IMU a real one's.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any
from urllib.parse import urlsplit

from drivers.codecs import msp
from drivers.contracts import Clock, Fault, MonotonicClock, Sensor
from drivers.errors import DeviceError
from drivers.hexapod_contracts import Hexapod, HexapodLimits
from drivers.imu_wire import HeldUploads, PacedClock
from drivers.sim.imu_rig import SimImuRig, imu_model

if TYPE_CHECKING:
    from drivers.wire_sim.pi_hexapod import SimPiController

__all__ = ["OpenImuRig", "open_imu_rig"]

ROLES = ("hexapod", "imu", "reference_imu")
SIM_HOST = "sim"  # tcp://sim[:port]: the simulated PI controller on loopback
SERIAL_PROTOCOL = {"imu": "msp", "reference_imu": "gx3"}  # the one backend per role


@dataclass
class OpenImuRig:
    """Opened devices of one IMU bench. ``sim`` is set on simulated rigs (truth, faults)."""

    clock: Clock
    hexapod: Hexapod
    imu: Sensor
    reference_imu: Sensor | None = None
    sim: SimImuRig | None = None
    close_errors: list[str] = field(default_factory=list)
    wire: SimPiController | None = None  # the simulated controller of a tcp://sim hexapod
    peers: dict[str, Any] = field(default_factory=dict)  # role -> serial://sim peer (pty)

    @property
    def sensors(self) -> dict[str, Sensor]:
        out: dict[str, Sensor] = {"imu": self.imu}
        if self.reference_imu is not None:
            out["reference_imu"] = self.reference_imu
        return out

    def close(self) -> list[str]:
        """Stop the hexapod first, then close everything; never raises (it runs in
        ``finally`` blocks); returns the errors, also kept in ``close_errors``."""
        errors = []
        for action in (self.hexapod.stop, self.hexapod.close, self.imu.close,
                       *((self.reference_imu.close,) if self.reference_imu else ())):
            try:
                action()
            except Exception as exc:  # every device gets closed
                errors.append(f"{type(exc).__name__}: {exc}")
        if self.wire is not None:
            self.wire.stop()
        for peer in self.peers.values():
            try:
                peer.stop()
            except Exception as exc:
                errors.append(f"{type(exc).__name__}: {exc}")
        self.close_errors = errors
        return errors

    def __enter__(self) -> OpenImuRig:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _faults(device: Any, options: Mapping[str, Any], role: str) -> None:
    unknown = sorted(set(options) - {"faults"})
    if unknown:
        raise DeviceError(f"{role}: simulated devices take only the option 'faults', "
                          f"got {', '.join(map(repr, unknown))}")
    for spec in options.get("faults", []):
        spec = dict(spec)
        try:
            device.inject(Fault(spec.pop("kind")), **spec)
        except (KeyError, ValueError, TypeError) as exc:
            raise DeviceError(f"{role}: bad fault spec {spec!r}: {exc}") from None


def _open_pi_hexapod(rig: Any, url: str, options: Mapping[str, Any], clock: Clock,
                     default_timeout_s: float) -> Hexapod:
    """The PI GCS backend on ``url`` (tcp://host:port), set up from the rig file."""
    from drivers.backends.pi_hexapod import (
        DEFAULT_DERIVATIVE_WINDOW,
        GcsDialect,
        PiHexapod,
        open_tcp,
    )
    from drivers.codecs.gcs import PORT

    parts = urlsplit(url)
    where = f"{rig.path}: [devices.hexapod] options"
    opts = dict(options)
    try:
        timeout_s = float(opts.pop("timeout_s", default_timeout_s))
        tolerance = float(opts.pop("start_tolerance", 1e-6))
        window = int(opts.pop("derivative_window", DEFAULT_DERIVATIVE_WINDOW))
    except (TypeError, ValueError) as exc:
        raise DeviceError(f"{where}: {exc}") from None
    if window > 3 and window % 2 == 0:
        raise DeviceError(f"{where}: derivative_window {window}: expected an odd number of "
                          "points (or 3 for plain differences)")
    dialect = GcsDialect.from_options(opts, where)
    host, port = parts.hostname or "", parts.port or PORT

    def connect() -> Any:
        return open_tcp(host, port, timeout_s=min(timeout_s, 2.0))

    sock = connect()
    try:
        return PiHexapod(sock, url=url, timeout_s=timeout_s, connect=connect,
                         limits=rig.hexapod.hexapod_limits(), clock=clock,
                         log_rate_hz=rig.hexapod.log_rate_hz, dialect=dialect,
                         start_tolerance=tolerance, derivative_window=window)
    except BaseException:
        sock.close()
        raise


def _simulated(url: str) -> bool:
    parts = urlsplit(url)
    return parts.scheme == "sim" or parts.hostname == SIM_HOST


def _serial_imu(rig: Any, role: str, clock: Clock, sim: SimImuRig | None,
                time_scale: float) -> Sensor:
    """The MSP IMU under test or the GX3 reference on a real port or a simulated peer."""
    from drivers.device_options import parse_device
    from drivers.imu_wire import (
        BTFL_ACC_1G,
        Gx3Reference,
        MspImuSensor,
        start_gx3_peer,
        start_msp_peer,
    )

    spec = parse_device(rig.path, role, rig.devices[role])
    want = SERIAL_PROTOCOL[role]
    spec.text("protocol", want, choices=(want,))
    if spec.is_wire_sim:
        spec.number("time_scale", 1.0, lo=1e-3, hi=1e3)  # read by open_imu_rig
    baud = spec.integer("baud", 115_200, lo=50, hi=20_000_000)
    try:
        from drivers.backends import serial_link
    except ImportError as exc:
        raise spec.fail("", f"serial devices need the Python package pyserial ({exc})") from None
    peer = None
    if role == "imu":
        from drivers.backends import msp_fc

        variant = spec.text("sim_variant", "BTFL", choices=("BTFL", "INAV")) \
            if spec.is_wire_sim else ""
        acc_1g = spec.number("acc_1g", lo=1.0, hi=32768.0) if spec.has("acc_1g") else None
        rate_hz = spec.number("rate_hz", rig.imu.value("rate_hz"), lo=0.1, hi=2000.0)
        timeout_s = spec.number("timeout_s", msp_fc.DEFAULT_TIMEOUT_S, lo=0.005, hi=5.0)
        version = spec.integer("msp_version", 1, lo=1, hi=2)
        if sim is not None:
            sim_1g = msp.INAV_ACC_1G if variant == "INAV" else spec.integer(
                "sim_acc_1g", BTFL_ACC_1G, lo=1, hi=32767)  # the simulated FC's driver
            peer = start_msp_peer(sim, clock, variant=variant, acc_1g=round(sim_1g))
    else:
        window_s = spec.number("time_window_s", 5.0, lo=0.1, hi=3600.0)
        stale_s = spec.number("stale_s", 0.2, lo=0.01, hi=60.0)
        open_timeout_s = spec.number("open_timeout_s", 1.0, lo=0.05, hi=30.0)
        if sim is not None:
            peer = start_gx3_peer(sim, clock)
    spec.check_used()
    path = peer.path if peer is not None else (spec.host + spec.path if spec.host
                                               else spec.path)
    if not path:
        if peer is not None:
            peer.stop()
        raise spec.fail("", "expected serial://<port>, e.g. serial:///dev/ttyUSB0 or "
                            f"serial://COM3, or serial://{SIM_HOST}/<name> for the simulator")
    port = None
    try:
        port = serial_link.open_port(path, baud)
        if role == "imu":
            client = msp_fc.MspClient(port, spec.url, timeout_s=timeout_s, version=version)
            if acc_1g is None and client.identify()[0] == "BTFL":
                acc_1g = BTFL_ACC_1G  # documented default; INAV's 1 g is always 512
            dev: Sensor = MspImuSensor(msp_fc.MspImu(
                client, rate_hz=rate_hz * time_scale, acc_1g=acc_1g, clock=clock,
                url=spec.url, attitude=False), rate_hz, port=port, peer=peer)
        else:
            from drivers.backends.gx3_imu import Gx3Imu
            from drivers.codecs import gx3

            dev = Gx3Reference(Gx3Imu(port, packet=gx3.EULER_RATES, clock=clock,
                                      stale_s=stale_s * time_scale, open_timeout_s=open_timeout_s,
                                      url=spec.url), window_s=window_s, port=port, peer=peer)
    except BaseException as exc:
        if port is not None:
            port.close()
        if peer is not None:
            peer.stop()
        if isinstance(exc, DeviceError) and not str(exc).startswith(str(rig.path)):
            raise DeviceError(f"{spec.where} {spec.url!r}: {exc}") from None
        raise
    return dev


def _time_scale(rig: Any) -> float | None:
    """``time_scale`` of the serial peers (they must agree); None without serial peers."""
    scales = {}
    for role in SERIAL_PROTOCOL:
        dev = rig.devices.get(role)
        if dev is None or not dev.url.startswith(f"serial://{SIM_HOST}"):
            continue
        from drivers.device_options import parse_device

        spec = parse_device(rig.path, role, dev)
        scales[role] = spec.number("time_scale", 1.0, lo=1e-3, hi=1e3)
    if len(set(scales.values())) > 1:
        raise DeviceError(f"{rig.path}: [devices.*] options.time_scale: the simulated serial "
                          f"devices must agree, got {scales}")
    return next(iter(scales.values()), None)


def open_imu_rig(rig: Any, *, seed: int | None = None) -> OpenImuRig:
    """Open the hexapod, the IMU and the reference IMU a rig config names."""
    devices = rig.devices
    for role, dev in devices.items():
        scheme = urlsplit(dev.url).scheme
        ok = ("sim", "tcp") if role == "hexapod" else ("sim", "serial")
        if scheme not in ok:
            what = ("sim://hexapod or a PI GCS controller at tcp://host[:port]"
                    if role == "hexapod" else
                    f"sim://{role.replace('_', '-')} or serial://<port> "
                    f"(protocol {SERIAL_PROTOCOL[role]})")
            raise DeviceError(f"{rig.path}: [devices.{role}] url {dev.url!r}: expected {what}")
    real = [r for r, d in devices.items() if not _simulated(d.url)]
    if real and len(real) != len(devices):
        sims = [r for r in devices if r not in real]
        raise DeviceError(f"{rig.path}: [devices] {', '.join(real)} real but "
                          f"{', '.join(sims)} simulated: a real hexapod needs a real IMU "
                          "under test (and a real IMU a real hexapod: neither sees the other's "
                          "motion); make them all real or all simulated (sim://, "
                          f"tcp://{SIM_HOST}, serial://{SIM_HOST}/...)")
    if real:
        return _open_real(rig)
    return _open_simulated(rig, seed)


def _open_real(rig: Any) -> OpenImuRig:
    clock = MonotonicClock()
    hex_dev = rig.devices["hexapod"]
    opened: list[Any] = []
    try:
        hexapod = _open_pi_hexapod(rig, hex_dev.url, hex_dev.options, clock,
                                   default_timeout_s=2.0)
        opened.append(hexapod)
        imu = _serial_imu(rig, "imu", clock, None, 1.0)
        opened.append(imu)
        ref = (_serial_imu(rig, "reference_imu", clock, None, 1.0)
               if "reference_imu" in rig.devices else None)
    except BaseException:
        for dev in reversed(opened):
            try:
                if dev is opened[0]:
                    dev.stop()
                dev.close()
            except Exception:  # the open error is the one to report
                pass
        raise
    return OpenImuRig(clock, hexapod, imu, ref)


def _open_simulated(rig: Any, seed: int | None) -> OpenImuRig:
    devices = rig.devices
    hex_dev = devices["hexapod"]
    parts = urlsplit(hex_dev.url)
    time_scale = _time_scale(rig)
    try:
        model = imu_model({**dict(rig.imu.params), **dict(rig.sim.imu)}, noise=rig.sim.noise)
    except KeyError as exc:
        raise DeviceError(f"{rig.path}: unknown IMU parameter {exc}") from None
    hx = rig.hexapod
    clock = PacedClock(time_scale) if time_scale is not None else None
    sim = SimImuRig(model, HexapodLimits(**dict(hx.limits)), seed=int(
        rig.sim.seed if seed is None else seed), log_rate_hz=hx.log_rate_hz,
        cg_m=tuple(rig.sim.cg_m) if rig.sim.cg_m is not None else tuple(hx.pivot_m),
        reference=dict(rig.reference_imu), clock=clock)
    sensors: dict[str, Sensor] = {}
    peers: dict[str, Any] = {}
    wire = None
    try:
        for role, fallback in (("imu", sim.imu), ("reference_imu", sim.reference_imu)):
            if role not in devices:
                continue
            if urlsplit(devices[role].url).scheme == "sim":
                _faults(fallback, devices[role].options, role)
                sensors[role] = fallback
            else:
                sensors[role] = _serial_imu(rig, role, sim.clock, sim, time_scale or 1.0)
                peers[role] = sensors[role].peer  # type: ignore[attr-defined]
        if parts.scheme == "sim":
            _faults(sim.hexapod, hex_dev.options, "hexapod")
            hexapod: Hexapod = sim.hexapod
        else:
            from drivers.wire_sim.pi_hexapod import SimPiController

            try:
                lim = sim.hexapod.limits()  # the controller's soft limits: the plant's own
                mm, deg = lim.position_m * 1e3, math.degrees(lim.angle_rad)
                travel = {a: (-mm, mm) for a in "XYZ"} | {a: (-deg, deg) for a in "UVW"}
                wire = SimPiController(plant=sim.hexapod, port=parts.port or 0,
                                       travel=travel).start()
            except OSError as exc:
                raise DeviceError(f"hexapod: {hex_dev.url!r}: cannot start the simulated "
                                  f"controller on port {parts.port} ({exc})") from None
            host, port = wire.address
            hexapod = _open_pi_hexapod(rig, f"tcp://{host}:{port}", hex_dev.options,
                                       sim.clock, default_timeout_s=2.0)
            if clock is not None:
                hexapod = HeldUploads(hexapod, clock)  # type: ignore[assignment]
    except BaseException:
        for sensor in sensors.values():
            if sensor is not sim.imu and sensor is not sim.reference_imu:
                sensor.close()
        for peer in peers.values():
            peer.stop()
        if wire is not None:
            wire.stop()
        raise
    return OpenImuRig(sim.clock, hexapod, sensors["imu"], sensors.get("reference_imu"), sim,
                      wire=wire, peers=peers)
