"""IMU-bench rig URLs -> devices: the hexapod, the IMU under test, the reference IMU.

``open_imu_rig(rig)`` takes a validated IMU rig config (``bench.imu_rig.ImuRigConfig``,
duck-typed so ``drivers`` does not import ``bench``). ``sim://`` devices come from one
seeded :class:`~drivers.sim.imu_rig.SimImuRig`. Real backends plug in here once they fill
the contracts of :mod:`drivers.hexapod_contracts`; until then other schemes raise
``DeviceError`` naming the device and what is missing.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import urlsplit

from drivers.contracts import Clock, Fault, Sensor
from drivers.errors import DeviceError
from drivers.hexapod_contracts import Hexapod, HexapodLimits
from drivers.sim.imu_rig import SimImuRig, imu_model

__all__ = ["OpenImuRig", "open_imu_rig"]

ROLES = ("hexapod", "imu", "reference_imu")
_NOT_YET = {
    "hexapod": "the PI GCS backend (drivers.backends.pi_hexapod) moves and stops the platform "
               "but has no trajectory upload (wave tables) or data-recorder read-back yet, "
               "so it does not fill drivers.hexapod_contracts.Hexapod",
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


def open_imu_rig(rig: Any, *, seed: int | None = None) -> OpenImuRig:
    """Open the hexapod, the IMU and the reference IMU a rig config names."""
    devices = rig.devices
    for role in ROLES:
        if role not in devices:
            continue
        url = devices[role].url
        if urlsplit(url).scheme != "sim":
            raise DeviceError(f"{role}: {url!r}: {_NOT_YET[role]}; use sim:// for now")
    try:
        model = imu_model({**dict(rig.imu.params), **dict(rig.sim.imu)}, noise=rig.sim.noise)
    except KeyError as exc:
        raise DeviceError(f"{rig.path}: unknown IMU parameter {exc}") from None
    hx = rig.hexapod
    sim = SimImuRig(model, HexapodLimits(**dict(hx.limits)), seed=int(
        rig.sim.seed if seed is None else seed), log_rate_hz=hx.log_rate_hz,
        cg_m=tuple(rig.sim.cg_m) if rig.sim.cg_m is not None else tuple(hx.pivot_m),
        reference=dict(rig.reference_imu))
    _faults(sim.hexapod, devices["hexapod"].options, "hexapod")
    _faults(sim.imu, devices["imu"].options, "imu")
    ref = None
    if "reference_imu" in devices:
        ref = sim.reference_imu
        _faults(ref, devices["reference_imu"].options, "reference_imu")
    return OpenImuRig(sim.clock, sim.hexapod, sim.imu, ref, sim)
