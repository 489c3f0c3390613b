"""IMU-bench rig URLs -> devices: the hexapod, the IMU under test, the reference IMU.

``open_imu_rig(rig)`` takes a validated IMU rig config (``bench.imu_rig.ImuRigConfig``,
duck-typed so ``drivers`` does not import ``bench``). ``sim://`` devices come from one
seeded :class:`~drivers.sim.imu_rig.SimImuRig`. The hexapod may instead be a PI GCS
controller over TCP (:class:`drivers.backends.pi_hexapod.PiHexapod`, limits and log rate
from the rig file): ``tcp://sim[:port]`` starts the simulated controller
(:class:`drivers.wire_sim.pi_hexapod.SimPiController`) on loopback, driven by the same
simulated hexapod plant the ``sim://`` IMUs read, and connects the real backend to it.
A real hexapod (``tcp://host[:port]``) needs a real IMU under test, and no IMU backend
is wired to the IMU bench yet: such rigs raise ``DeviceError`` naming what is missing.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any
from urllib.parse import urlsplit

from drivers.contracts import Clock, Fault, Sensor
from drivers.errors import DeviceError
from drivers.hexapod_contracts import Hexapod, HexapodLimits
from drivers.sim.imu_rig import SimImuRig, imu_model

if TYPE_CHECKING:
    from drivers.wire_sim.pi_hexapod import SimPiController

__all__ = ["OpenImuRig", "open_imu_rig"]

ROLES = ("hexapod", "imu", "reference_imu")
SIM_HOST = "sim"  # tcp://sim[:port]: the simulated PI controller on loopback
_NOT_YET = {
    "imu": "no IMU-under-test backend is wired to the IMU bench yet",
    "reference_imu": "no reference-IMU backend is wired to the IMU bench yet",
}


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


def open_imu_rig(rig: Any, *, seed: int | None = None) -> OpenImuRig:
    """Open the hexapod, the IMU and the reference IMU a rig config names."""
    devices = rig.devices
    for role in ("imu", "reference_imu"):
        if role in devices and urlsplit(devices[role].url).scheme != "sim":
            raise DeviceError(f"{role}: {devices[role].url!r}: {_NOT_YET[role]}; use sim:// "
                              "for now")
    hex_dev = devices["hexapod"]
    parts = urlsplit(hex_dev.url)
    if parts.scheme == "tcp" and parts.hostname != SIM_HOST:
        raise DeviceError(f"hexapod: {hex_dev.url!r}: a real hexapod needs a real IMU under "
                          f"test ({_NOT_YET['imu']}); the sim:// IMUs read the simulated "
                          f"hexapod's motion: use tcp://{SIM_HOST} to run the PI backend "
                          "against the simulated controller")
    if parts.scheme not in ("sim", "tcp"):
        raise DeviceError(f"hexapod: {hex_dev.url!r}: expected sim://hexapod or a PI GCS "
                          "controller at tcp://host[:port]")
    try:
        model = imu_model({**dict(rig.imu.params), **dict(rig.sim.imu)}, noise=rig.sim.noise)
    except KeyError as exc:
        raise DeviceError(f"{rig.path}: unknown IMU parameter {exc}") from None
    hx = rig.hexapod
    sim = SimImuRig(model, HexapodLimits(**dict(hx.limits)), seed=int(
        rig.sim.seed if seed is None else seed), log_rate_hz=hx.log_rate_hz,
        cg_m=tuple(rig.sim.cg_m) if rig.sim.cg_m is not None else tuple(hx.pivot_m),
        reference=dict(rig.reference_imu))
    _faults(sim.imu, devices["imu"].options, "imu")
    ref = None
    if "reference_imu" in devices:
        ref = sim.reference_imu
        _faults(ref, devices["reference_imu"].options, "reference_imu")
    if parts.scheme == "sim":
        _faults(sim.hexapod, hex_dev.options, "hexapod")
        return OpenImuRig(sim.clock, sim.hexapod, sim.imu, ref, sim)
    from drivers.wire_sim.pi_hexapod import SimPiController

    try:
        wire = SimPiController(plant=sim.hexapod, port=parts.port or 0).start()
    except OSError as exc:
        raise DeviceError(f"hexapod: {hex_dev.url!r}: cannot start the simulated controller "
                          f"on port {parts.port} ({exc})") from None
    host, port = wire.address
    try:
        hexapod = _open_pi_hexapod(rig, f"tcp://{host}:{port}", hex_dev.options, sim.clock,
                                   default_timeout_s=2.0)
    except BaseException:
        wire.stop()
        raise
    return OpenImuRig(sim.clock, hexapod, sim.imu, ref, sim, wire=wire)
