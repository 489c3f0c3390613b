"""The IMU bench's wire-level simulated devices, in a process of their own when all are.

Why: the hexapod controller (loopback TCP), the MSP flight controller and the 3DM-GX3 (ptys)
stand for firmware with processors of their own; as threads of the bench's process they
shared its interpreter lock, and a loaded host starved them (late MSP replies, a silent
GX3). A rig whose devices are all wire-level (``tcp://sim``, ``serial://sim/...``) gets its
world served by a child (:class:`drivers.wire_sim.world_process.WorldProcess`, started by
``drivers.sim_worlds.imu_world_process``):
:class:`ImuWireWorld` there (the ``SimImuRig`` on its paced clock, its devices by key),
:class:`RemoteImuWorld` here. Rigs that mix in ``sim://`` devices or a launched firmware
read the world in this process, and get the same devices from :func:`start_imu_device`.

One time base: the child's :class:`~drivers.wire_sim.paced_clock.PacedClock` and the host's
:class:`HostPacedClock` share their epoch and scale, so both read the same bench time from
the system-wide monotonic clock with no request per reading; a hold (trajectory upload) is
made in both, here first, so this clock never reads ahead of the world's held time.
Neither pauses for a starved process: the other could not know.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from drivers.errors import DeviceError
from drivers.wire_sim.paced_clock import PacedClock
from drivers.wire_sim.world_process import FastSwitching, Remote, RemoteDevice, WorldProcess

if TYPE_CHECKING:  # the IMU world (scipy) loads only where it runs
    from drivers.sim.imu_rig import SimImuRig

__all__ = ["IMU_DEVICES", "HostPacedClock", "ImuWireWorld", "RemoteImuWorld",
           "start_imu_device"]


def _start_hexapod(sim: SimImuRig, port: int) -> Any:
    """The simulated PI controller on loopback, driving the world's hexapod plant."""
    from drivers.wire_sim.pi_hexapod import SimPiController

    lim = sim.hexapod.limits()  # the controller's soft limits: the plant's own
    mm, deg = lim.position_m * 1e3, math.degrees(lim.angle_rad)
    travel = {a: (-mm, mm) for a in "XYZ"} | {a: (-deg, deg) for a in "UVW"}
    try:
        return SimPiController(plant=sim.hexapod, port=port, travel=travel).start()
    except OSError as exc:
        raise DeviceError(f"cannot start the simulated controller on port {port} "
                          f"({exc})") from None


def _start_msp(sim: SimImuRig, variant: str, acc_1g: int) -> Any:
    from drivers.wire_sim.plant_peers import start_msp_peer

    return start_msp_peer(sim, sim.clock, variant=variant, acc_1g=acc_1g)


def _start_gx3(sim: SimImuRig) -> Any:
    from drivers.wire_sim.plant_peers import start_gx3_peer

    return start_gx3_peer(sim, sim.clock)


#: kind -> ``start(sim, *args)``: the device started and driven by the world ``sim``
IMU_DEVICES: dict[str, Callable[..., Any]] = {
    "hexapod": _start_hexapod, "msp": _start_msp, "gx3": _start_gx3}


def _where(device: Any) -> str | tuple[str, int]:
    """What the host opens: the pty's path, or the controller's loopback address."""
    address = getattr(device, "address", None)
    return tuple(address) if address is not None else device.path


class ImuWireWorld:
    """The world in its process: the simulated IMU bench and its devices, by key."""

    def __init__(self, sim: SimImuRig) -> None:
        self.sim = sim
        self.clock = sim.clock
        self.peers: dict[str, Any] = {}

    def start(self, key: str, kind: str, args: tuple = ()) -> str | tuple[str, int]:
        """Start ``IMU_DEVICES[kind]`` (once per ``key``); returns what to open."""
        if key not in self.peers:
            self.peers[key] = IMU_DEVICES[kind](self.sim, *args)
        return _where(self.peers[key])

    def truth(self) -> dict[str, Any]:
        return self.sim.truth()

    def close(self) -> None:
        for device in reversed(list(self.peers.values())):
            try:
                device.stop()
            except Exception:  # every device gets stopped; the process ends anyway
                pass
        self.peers.clear()


class HostPacedClock(PacedClock):
    """The bench's reading of the world process's paced clock (same epoch, same scale, no
    pauses). The world's clock decides a hold's instant and its end, so the devices' time
    runs on without a step; this one follows (it stands still meanwhile)."""

    def __init__(self, time_scale: float) -> None:
        super().__init__(time_scale, max_gap_s=math.inf)
        self.world: Remote | None = None  # the world's clock, once its process runs
        # bench time the last freeze stepped forward to meet the world's held instant:
        # the freeze request's trip to the world, the only bench time a hold takes here
        self.freeze_step_s = 0.0

    def freeze(self, held_ns: int | None = None) -> int:
        """Held here first, then in the world, then here at the world's held instant (a
        step forward). Held in the world first, this clock ran on through the request's
        round trip, ahead of the world's: an MSP poll sent then and served by the held
        world read ``sent - served`` too large by that round trip (5 ms of wall time on a
        loaded machine, 25 ms of bench time at 6x), and the FC-clock offset, the largest
        over 400 rows, stamped the next 4 s of rows that much late (K_w 0.86 % off)."""
        if self.world is None:
            return super().freeze(held_ns)
        own_ns = super().freeze()
        try:
            world_ns: int = self.world.freeze()
        except DeviceError:  # the world is gone: this clock runs on alone
            super().resume()
            raise
        self.freeze_step_s = (world_ns - own_ns) * 1e-9
        return super().freeze(world_ns)

    def resume(self, epoch: float | None = None) -> float:
        if self.world is not None:
            try:
                epoch = self.world.resume()
            except DeviceError:  # the world is gone: this clock runs on alone
                super().resume()
                raise
        return super().resume(epoch)


class RemoteImuWorld:
    """The host's handle on an :class:`ImuWireWorld` in its process: what the bench reads of
    the world (``truth()`` for run.json's ``sim_truth``; ``model`` and the ``hexapod`` plant
    for checks) and the devices it starts there."""

    def __init__(self, process: WorldProcess, clock: HostPacedClock) -> None:
        self.process = process  # serving an ImuWireWorld on ``clock``'s epoch and scale
        self.clock = clock
        clock.world = Remote(self.process, None, ("clock",))
        self.hexapod = Remote(self.process, None, ("sim", "hexapod"))  # the plant
        self.peers: dict[str, RemoteDevice] = {}
        # the host polls the world hundreds of times a second: see FastSwitching
        self._switching: FastSwitching | None = FastSwitching().__enter__()

    def start(self, key: str, kind: str, args: tuple = ()) -> RemoteDevice:
        if key not in self.peers:
            where = self.process.request("call", None, ("start",), (key, kind, args))
            self.peers[key] = RemoteDevice(self.process, key, where)
        return self.peers[key]

    def truth(self) -> dict[str, Any]:
        return self.process.request("call", None, ("truth",))

    @property
    def model(self) -> Any:
        """The IMU model under test (a copy: the world's is in its process)."""
        return self.process.request("get", None, ("sim", "model"))

    def close(self) -> None:
        """Stops the devices, then the process; the clock runs on alone."""
        self.clock.world = None
        self.peers.clear()
        if self._switching is not None:
            self._switching.__exit__(None, None, None)
            self._switching = None
        self.process.close()


def start_imu_device(ctx: Any, key: str, kind: str, *args: Any) -> Any:
    """The IMU bench's simulated device ``kind`` for ``key`` (once): started in the world's
    process if it has one (a :class:`RemoteDevice`), else here (stopped with the rig).
    Either way its ``path`` (pty) or ``address`` (loopback) is what the backend opens."""
    world = ctx.world()
    if isinstance(world, RemoteImuWorld):
        return world.start(key, kind, args)
    return ctx.shared(("imu-device", key), lambda: IMU_DEVICES[kind](world, *args),
                      lambda device: device.stop())
