"""The simulated world behind a rig file's simulated devices, one builder per bench.

``sim://<role>`` devices read a seeded world on its own fast simulated clock; the host
``sim`` of wire-level URLs (``serial://sim/...``, ``can://sim/...``, ``tcp://sim``) starts
peers that the same world drives on the wall clock. Each bench brings its world:

* the propulsion stand: :func:`build_sim_rig` (``drivers.sim.rig.SimRig`` from the rig's
  ``[sim]`` and ``[esc]`` tables); its wire peers run on a
  :class:`drivers.wire_sim.plant_peers.WirePlant` (:func:`wire_plant`), in a child
  process of its own with its serial peers;
* the IMU bench: :func:`build_sim_imu_rig` (``drivers.sim.imu_rig.SimImuRig``), on a
  :class:`drivers.wire_sim.paced_clock.PacedClock` when serial peers need the wall clock;
  when every device is wire-level, in a child process with them
  (``drivers.wire_sim.imu_world``).

:func:`sim_faults` applies the faults a rig file schedules on a simulated device.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from drivers.contracts import Fault
from drivers.errors import DeviceError
from drivers.rig_view import RigView, imu_sim, propulsion_sim, section
from drivers.sim.esc import EscSettings
from drivers.sim.plant import PlantParams
from drivers.sim.rig import SimRig
from drivers.sim.sensor_params import SensorParams

if TYPE_CHECKING:  # the IMU world (scipy splines) loads only for an IMU bench
    from drivers.sim.imu_rig import SimImuRig

__all__ = ["PROPULSION_SENSORS", "build_sim_imu_rig", "build_sim_rig", "imu_wire_world",
           "imu_world_process", "sim_faults", "wire_plant", "wire_sims"]

PROPULSION_SENSORS = ("load_cell", "power", "rpm")


def sim_faults(device: Any, options: Mapping[str, Any], role: str, table: str = "") -> None:
    """Faults scheduled in a rig file: ``options.faults = [{kind = "dropout", at_s = 2}]``.

    ``table`` (``<rig file>: [devices.<role>]``) makes the messages name file and key.
    """
    unknown = sorted(set(options) - {"faults"})
    if unknown:
        where = f"{table} options.{unknown[0]}" if table else role
        raise DeviceError(f"{where}: simulated devices take only the option 'faults', "
                          f"got {', '.join(map(repr, unknown))}")
    faults = options.get("faults", [])
    if not isinstance(faults, list | tuple):
        raise DeviceError(f"{table or role} options.faults: expected a list of tables, "
                          f"got {faults!r}")
    for spec in faults:
        try:
            kwargs = dict(spec)
            kind = Fault(kwargs.pop("kind"))
            device.inject(kind, **kwargs)
        except (KeyError, ValueError, TypeError) as exc:
            where = f"{table} options.faults" if table else role
            raise DeviceError(f"{where}: bad fault spec {spec!r}: {exc}") from None


def build_sim_rig(rig: RigView, *, seed: int | None = None, urls: dict[str, str] | None = None,
                  calibrations: bool = False) -> SimRig:
    """The seeded simulated propulsion rig of a rig file's ``[sim]`` and ``[esc]`` tables.

    ``calibrations``: take the sensors' calibration tables from the rig's devices (the
    ``sim://`` rig); wire-level peers report calibrated values like their firmware.
    """
    sim = propulsion_sim(rig)
    try:
        params = PlantParams.with_overrides(dict(sim.plant))
        sensor_params = SensorParams.with_overrides(
            {"noise": bool(sim.noise), **dict(sim.sensors)})
    except KeyError as exc:
        raise DeviceError(f"{rig.path}: [sim] unknown plant/sensor parameter {exc}") from None
    e = section(rig, rig.esc, "esc")
    esc_settings = EscSettings(e.frame_rate_hz, e.min_us, e.max_us, e.idle_us, e.arm_us,
                               e.timeout_s)
    devices = rig.devices
    cal = {role: dict(devices[role].calibration) if calibrations else {}
           for role in PROPULSION_SENSORS}
    return SimRig(
        params=params,
        sensor_params=sensor_params,
        esc_settings=esc_settings,
        esc_mode=sim.esc_mode,
        seed=int(sim.seed if seed is None else seed),
        urls=urls,
        load_cell_cal=cal["load_cell"],
        power_cal=cal["power"],
        rpm_cal=cal["rpm"],
    )


def wire_plant(rig: RigView, seed: int | None = None) -> Any:
    """The propulsion plant on the wall clock, owner of the rig's wire-level peers (a
    launched firmware's plant peer too): served with them by a child process
    (``drivers.wire_sim.world_process``)."""
    from drivers.wire_sim.plant_peers import ProcessWireSims, RemotePlant
    from drivers.wire_sim.world_process import WorldProcess

    return ProcessWireSims(RemotePlant(WorldProcess(wire_sims, rig, seed, name="wire-plant")))


def wire_sims(rig: RigView, seed: int | None = None) -> Any:
    """The propulsion plant and its peers in this process (the world process's world)."""
    from drivers.wire_sim.plant_peers import WirePlant, WireSims

    return WireSims(WirePlant(build_sim_rig(rig, seed=seed)))


def build_sim_imu_rig(rig: RigView, seed: int | None, time_scale: float | None, *,
                      epoch: float | None = None) -> SimImuRig:
    """The seeded simulated IMU bench; on the wall clock (``time_scale``) if not None. With
    ``epoch`` (monotonic wall time of bench time 0) the clock is one another process reads
    too (``drivers.wire_sim.imu_world``): it never pauses for a starved process."""
    from drivers.sim.imu_rig import SimImuRig, imu_model

    sim = imu_sim(rig)
    imu = section(rig, rig.imu, "imu")
    try:
        model = imu_model({**dict(imu.params), **dict(sim.imu)}, noise=sim.noise)
    except KeyError as exc:
        raise DeviceError(f"{rig.path}: unknown IMU parameter {exc}") from None
    clock = None
    if time_scale is not None:
        from drivers.wire_sim.paced_clock import PacedClock

        clock = PacedClock(time_scale) if epoch is None else PacedClock(
            time_scale, max_gap_s=math.inf, epoch=epoch)
    hx = section(rig, rig.hexapod, "hexapod")
    reference = section(rig, rig.reference_imu, "reference_imu")
    return SimImuRig(model, hx.hexapod_limits(), seed=int(
        sim.seed if seed is None else seed), log_rate_hz=hx.log_rate_hz,
        cg_m=sim.cg_m if sim.cg_m is not None else hx.pivot_m,
        reference=dict(reference), clock=clock)


def imu_world_process(rig: RigView, seed: int | None, clock: Any) -> Any:
    """The IMU bench's world and its wire devices served by a child process, its paced clock
    on the epoch and scale of ``clock`` (a ``drivers.wire_sim.imu_world.HostPacedClock``)."""
    from drivers.wire_sim.imu_world import RemoteImuWorld
    from drivers.wire_sim.world_process import WorldProcess

    return RemoteImuWorld(WorldProcess(imu_wire_world, rig, seed, clock.time_scale,
                                       clock.epoch, name="imu-world"), clock)


def imu_wire_world(rig: RigView, seed: int | None, time_scale: float, epoch: float) -> Any:
    """The IMU bench's world in its process (the world process's world)."""
    from drivers.wire_sim.imu_world import ImuWireWorld

    return ImuWireWorld(build_sim_imu_rig(rig, seed, time_scale, epoch=epoch))
