"""The simulated benches' plants driving wire-level simulated peers (``drivers.wire_sim``).

A rig file whose device URLs name the host ``sim`` (``serial://sim/msp``,
``serial://sim/loadcell``, ``can://sim/<channel>``,
``serial://sim/msp-imu``, ``serial://sim/gx3``) gets real backends talking to these
peers over a pty or python-can's ``virtual`` bus, byte for byte.

Propulsion stand: the peers take their physics from one :class:`WirePlant`: the same
seeded ``drivers.sim.rig.SimRig`` the plain simulated rig uses (plant, ESC firmware model,
load cell, current sensor, hall counter), whose simulated clock is pulled along with
``time.monotonic``. Commands that reach a peer go into the ESC firmware model at their
arrival time, so the wire's latency and the frame phase show up in the response exactly
as on a bench. Peers: a flight controller (MSP motor test) whose motor output feeds the
ESC model; a load-cell board printing one line per ``period_s`` with the mean of the
load-cell (and power-sensor) samples since its previous line (the boxcar of an integrating
ADC) and the latest hall-counter speed; a VESC and a DroneCAN ESC whose commands set the
duty and whose status broadcasts carry the plant's speed, currents and voltage.

IMU bench: the simulated IMU bench (:class:`drivers.sim.imu_rig.SimImuRig`) on a
:class:`drivers.wire_sim.paced_clock.PacedClock`. :func:`start_msp_peer` answers MSP from
the same IMU model ``sim://imu`` uses (mounting, scale, axes, lever arm, bias, noise):
the last sample of the FC's sensor loop (``FC_LOOP_HZ``) taken ``clock_offset_s`` before
the request arrived (the FC's sensor latency); :func:`start_gx3_peer` streams the
platform's attitude and rates with the reference's noise, its timer counting simulated
time. Both compute their readings a block at a time (``drivers.wire_sim.grid_sampler``).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from drivers.codecs import gx3, msp
from drivers.errors import DeviceError
from drivers.sim.clock import SimClock
from drivers.sim.rig import PlantTruth, SimRig
from drivers.wire_sim.grid_sampler import GridSampler

if TYPE_CHECKING:  # the IMU bench's world (scipy) loads only for its peers
    from drivers.sim.imu_rig import SimImuRig

__all__ = ["BTFL_ACC_1G", "CAN_PEERS", "ESC_TEMPERATURE_C", "SERIAL_PEERS", "ProcessWireSims",
           "RemotePlant", "WirePlant", "WireSims", "start_gx3_peer", "start_msp_peer"]

BTFL_ACC_1G = 2048  # protocols.md §1.4: Betaflight MPU6000/6050-class acc_1G (512 * 4), ±16 g
_MAX_BURST = 16  # GX3 packets written per wakeup of the simulated device at most
# The simulated FC's sensor loop (Betaflight's gyro loop runs at kilohertz rates): an MSP
# reply carries its latest sample, 0.5 ms old at most; and how much of its readings, and
# the GX3's stream, are computed in one call (drivers.wire_sim.grid_sampler)
FC_LOOP_HZ = 2000.0
_FC_BLOCK_S = 0.1
_GX3_BLOCK = 25

ESC_TEMPERATURE_C = 25.0  # the plant has no thermal model: telemetry reports ambient


class WirePlant:
    """A ``SimRig`` whose clock follows the wall clock; thread-safe entry points for peers.

    The ESC power stage is armed from power-up (it sees the controller's idle output) and
    gets the commanded pulse refreshed every ``refresh_s`` by a small thread, as the PWM
    line from a flight controller or the VESC's own control loop would; the failsafe of
    the wire protocols (VESC and DroneCAN command timeouts, a stalled host) is the peers'
    and the backends' business, as on real hardware.
    """

    def __init__(self, sim: SimRig, *, step_s: float = 0.01, refresh_s: float = 0.05) -> None:
        self.sim = sim
        self.settings = sim.esc_settings
        self._lock = threading.RLock()
        self._t0 = time.monotonic()
        self.pulse_us = self.settings.idle_us
        self.refresh_ns = round(refresh_s * 1e9)
        self._last_push_ns = 0
        self.changes: list[tuple[float, float]] = []  # (monotonic s, pulse us) per change
        self._means: dict[str, float] = {}
        self._last_read_ns = 0
        sim.esc_model.push(0, "arm")
        self._stop = threading.Event()
        self._step_s = step_s
        self._thread = threading.Thread(target=self._run, name="wire-plant", daemon=True)
        self._thread.start()

    # -- time -----------------------------------------------------------------------------
    def _advance(self) -> int:
        """Bring the simulated clock up to the wall clock; returns now in ns."""
        clock = self.sim.clock
        now = round((time.monotonic() - self._t0) * 1e9)
        if now > clock.now_ns():
            clock.sleep((now - clock.now_ns()) * 1e-9)
        return clock.now_ns()

    def _run(self) -> None:
        while not self._stop.wait(self._step_s):
            with self._lock:
                t = self._advance()
                if t - self._last_push_ns >= self.refresh_ns:
                    self.sim.esc_model.push(t, "pulse", self.pulse_us)
                    self._last_push_ns = t
                if t - self._last_read_ns > 500_000_000:
                    self.sensor_means()  # no board reads the sensors: keep the history short

    # -- commands ------------------------------------------------------------------------
    def command_pulse(self, pulse_us: float) -> None:
        """The power stage gets ``pulse_us`` from now on (clamped to the ESC range)."""
        s = self.settings
        pulse = min(s.max_us, max(s.min_us, float(pulse_us))) if math.isfinite(pulse_us) \
            else s.idle_us
        with self._lock:
            t = self._advance()
            self.sim.esc_model.push(t, "pulse", pulse)
            self._last_push_ns = t
            if pulse != self.pulse_us:
                self.changes.append((time.monotonic(), pulse))
            self.pulse_us = pulse

    def command_fraction(self, fraction: float) -> None:
        """A duty-type command 0..1 (VESC duty, DroneCAN raw / 8191) on the same scale."""
        s = self.settings
        f = min(1.0, max(0.0, fraction)) if math.isfinite(fraction) else 0.0
        self.command_pulse(s.min_us + f * (s.max_us - s.min_us))

    def idle_since(self) -> float | None:
        """Monotonic time of the last change to idle (None if not idle now)."""
        with self._lock:
            if self.pulse_us > self.settings.idle_us:
                return None
            for t, pulse in reversed(self.changes):
                if pulse <= self.settings.idle_us:
                    return t
            return None

    # -- measurements --------------------------------------------------------------------
    def truth(self) -> PlantTruth:
        with self._lock:
            self._advance()
            return self.sim.truth()

    def sensor_means(self) -> dict[str, float]:
        """Mean load-cell thrust, bus current and voltage since the previous call, and the
        latest hall-counter speed, from the simulated rig's own sensor models."""
        with self._lock:
            self._advance()
            self._last_read_ns = self.sim.clock.now_ns()
            out = dict(self._means)
            for sensor in self.sim.sensors.values():
                block = sensor.read_block()
                if len(block) == 0:
                    continue
                for name, v in block.values.items():
                    out[name] = float(v[-1]) if name == "rpm" else float(np.mean(v))
            self._means = out
        return out

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout=1.0)


@dataclass
class WireSims:
    """The peers started for one opened rig, and how to stop them (last, after the host)."""

    plant: Any  # a WirePlant here, a RemotePlant in the host's process
    peers: dict[str, Any] = field(default_factory=dict)
    _stops: list[Callable[[], None]] = field(default_factory=list)

    def add(self, key: str, peer: object, stop: Callable[[], None]) -> None:
        self.peers[key] = peer
        self._stops.append(stop)

    def start_peer(self, key: str, kind: str, args: tuple = ()) -> Any:
        """The serial peer ``SERIAL_PEERS[kind](plant, *args)`` (one per ``key``); its
        ``path`` is the pty to open."""
        if key not in self.peers:
            peer = SERIAL_PEERS[kind](self.plant, *args)
            self.add(key, peer, peer.stop)
        return self.peers[key]

    def peer_path(self, key: str, kind: str, args: tuple = ()) -> str:
        """:meth:`start_peer` for another process: what it opens."""
        return self.start_peer(key, kind, args).path

    def connect_can(self, channel: str, port: int) -> None:
        """The nodes' end of the host's CAN ``channel``: a socket to loopback ``port``."""
        import socket

        from drivers.wire_sim.can_socket import SocketCanLink

        link = SocketCanLink(socket.create_connection(("127.0.0.1", port)),
                             f"sim nodes on {channel}")
        self.add(f"can-link:{channel}", link, link.close)

    def start_sitl(self, key: str, motor_index: int, rate_hz: float) -> None:
        """The Betaflight SITL's plant peer (``drivers.wire_sim.sitl_plant``) on this
        plant, started: its UDP sockets and its FDM loop live with the plant."""
        from drivers.wire_sim.sitl_plant import SitlPlantPeer

        peer = SitlPlantPeer(self.plant, motor_index, rate_hz=rate_hz).start()
        self.add(key, peer, peer.stop)

    def start_can_peer(self, key: str, kind: str, channel: str, args: tuple = ()) -> None:
        """The CAN node ``CAN_PEERS[kind](plant, link, *args)`` on ``channel`` (one per
        ``key``)."""
        if key not in self.peers:
            peer = CAN_PEERS[kind](self.plant, self.peers[f"can-link:{channel}"], *args)
            self.add(key, peer, peer.stop)

    def close(self) -> None:
        errors = []
        for stop in reversed(self._stops):
            try:
                stop()
            except Exception as exc:  # every peer gets stopped
                errors.append(exc)
        self._stops.clear()
        self.peers.clear()
        self.plant.close()
        if errors:
            raise DeviceError(f"stopping the simulated wire devices: {errors[0]}")


class RemotePlant:
    """The host's handle on the :class:`WirePlant` in the world's process (the entry
    points the peers and the tests use; each a request over the pipe). Once closed, it
    answers ``pulse_us``, ``idle_since()`` and ``truth()`` with the plant's last state
    (what the ESC was left at when the rig closed)."""

    def __init__(self, world: Any) -> None:
        self.world = world  # a drivers.wire_sim.world_process.WorldProcess
        self._final: dict[str, Any] | None = None
        self.settings = self._get("settings")

    def _get(self, name: str) -> Any:
        if self._final is not None:
            return self._final[name]
        return self.world.request("get", None, ("plant", name))

    def _call(self, name: str, *args: Any) -> Any:
        if self._final is not None and not args:
            return self._final[name]
        return self.world.request("call", None, ("plant", name), args)

    @property
    def pulse_us(self) -> float:
        return self._get("pulse_us")

    def command_pulse(self, pulse_us: float) -> None:
        self._call("command_pulse", pulse_us)

    def command_fraction(self, fraction: float) -> None:
        self._call("command_fraction", fraction)

    def idle_since(self) -> float | None:
        return self._call("idle_since")

    def truth(self) -> PlantTruth:
        return self._call("truth")

    def sensor_means(self) -> dict[str, float]:
        return self._call("sensor_means")

    def close(self) -> None:
        """Stops the world's process (its peers and plant first)."""
        if self._final is None and self.world.alive:
            self._final = {"pulse_us": self.pulse_us, "idle_since": self.idle_since(),
                           "truth": self.truth()}
        self.world.close()


class ProcessWireSims(WireSims):
    """The host's side of a :class:`WireSims` served by a child process: its serial peers
    run there (handles: ``drivers.wire_sim.world_process.Remote`` with their ``path``);
    peers the host adds itself (CAN nodes on an in-process bus) drive the plant through
    :class:`RemotePlant`."""

    def start_peer(self, key: str, kind: str, args: tuple = ()) -> Any:
        if key not in self.peers:
            world = self.plant.world
            path = world.request("call", None, ("peer_path",), (key, kind, args))
            peer = world.remote(key)
            peer.path = path
            self.add(key, peer, peer.stop)
        return self.peers[key]

    def bridge_can(self, channel: str, link: Any) -> None:
        """Joins ``link`` (the nodes' end of the host's virtual ``channel``) to the world's
        nodes by a loopback socket (``drivers.wire_sim.can_socket``)."""
        from drivers.wire_sim.can_socket import bridge

        far, stop = bridge(link, lambda port: self.plant.world.request(
            "call", None, ("connect_can",), (channel, port)), f"world's nodes on {channel}")
        self.add(f"can-bridge:{channel}", far, stop)

    def sitl_peer(self, motor_index: int, rate_hz: float) -> Any:
        """A Betaflight SITL plant peer to start in the world's process (its handle:
        ``drivers.wire_sim.sitl_plant.RemoteSitlPeer``; ``start()`` starts it)."""
        from drivers.wire_sim.sitl_plant import RemoteSitlPeer

        return RemoteSitlPeer(self.plant.world, motor_index, rate_hz)

    def start_can_peer(self, key: str, kind: str, channel: str, args: tuple = ()) -> None:
        if key not in self.peers:
            world = self.plant.world
            world.request("call", None, ("start_can_peer",), (key, kind, channel, args))
            peer = world.remote(key)
            self.add(key, peer, peer.stop)


# -- propulsion peers ------------------------------------------------------------------
def _still_imu(_t: float):
    """A level, resting flight controller: gravity on z, no rotation."""
    from drivers.codecs.msp import STANDARD_GRAVITY

    return (0.0, 0.0, STANDARD_GRAVITY), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)


def start_msp_fc(plant: WirePlant, motor_index: int):
    """A flight controller on a pty whose motor-test output drives the plant's ESC."""
    from drivers.codecs import msp
    from drivers.wire_sim.msp_fc import SimFlightController

    class PlantFlightController(SimFlightController):
        def _reply(self, m: msp.MspMessage) -> bytes:
            out = super()._reply(m)
            if isinstance(m, msp.SetMotor):
                motors = self.motors()
                if motor_index < len(motors):
                    plant.command_pulse(motors[motor_index])
            return out

    return PlantFlightController(_still_imu).start()


def start_loadcell_board(plant: WirePlant, layout, period_s: float):
    """A line-printing board on a pty reporting the plant's sensors (see module doc)."""
    from drivers.wire_sim.loadcell_board import SimLoadcellBoard

    names = {f.name for f in layout.fields if f is not None}

    def model(t: float) -> dict[str, float]:
        m = plant.sensor_means()
        values = {n: 0.0 for n in names}
        values.update({k: v for k, v in m.items() if k in names and math.isfinite(v)})
        if "throttle_us" in names:
            values["throttle_us"] = plant.pulse_us
        if "t_s" in names:
            values["t_s"] = t
        return values

    return SimLoadcellBoard(layout, model, period_s=period_s).start()


def _vesc_fraction(cmd) -> float:
    """A VESC command as a duty fraction: current 0 / brake / release coast at 0."""
    return cmd.value if cmd.kind == "duty" else 0.0


def _vesc_state(plant: WirePlant, pole_pairs: int):
    """What a VESC on the plant reports (status broadcasts or GET_VALUES)."""
    from drivers.wire_sim.vesc import VescState

    tr = plant.truth()
    return VescState(erpm=tr.rpm * pole_pairs, motor_current_a=tr.current_winding_a,
                     duty=max(tr.duty, 0.0), input_current_a=tr.current_bus_a,
                     voltage_in_v=tr.voltage_bus_v, temp_fet_c=ESC_TEMPERATURE_C,
                     temp_motor_c=ESC_TEMPERATURE_C)


def start_vesc(plant: WirePlant, link, controller_id: int, pole_pairs: int,
               status_rate_hz: float):
    """A VESC on the bus; duty commands drive the plant, statuses report its state."""
    from drivers.codecs.can_log import CanFrame
    from drivers.wire_sim.vesc import SimVescDevice, VescCommand, VescState

    def model(_t: float, cmd: VescCommand) -> VescState:
        plant.command_fraction(_vesc_fraction(cmd))  # the firmware's timeout reaches the motor
        return _vesc_state(plant, pole_pairs)

    class PlantVesc(SimVescDevice):
        def _on_frame(self, frame: CanFrame) -> None:
            before = len(self.commands_seen)
            super()._on_frame(frame)
            if len(self.commands_seen) > before:  # a command for us: applied on arrival
                plant.command_fraction(_vesc_fraction(self.command))

    return PlantVesc(link, controller_id, model, status_rate_hz=status_rate_hz).start()


def start_dronecan_esc(plant: WirePlant, link, node_id: int, esc_index: int,
                       status_period_s: float):
    """A DroneCAN ESC node; RawCommand drives the plant, esc.Status reports its state."""
    from drivers.codecs import dronecan as dc
    from drivers.codecs.can_log import CanFrame
    from drivers.wire_sim.dronecan_esc import SimDroneCanEsc

    def model(_t: float, raw: int) -> dc.EscStatus:
        plant.command_fraction(max(raw, 0) / dc.RAW_MAX)
        tr = plant.truth()
        return dc.EscStatus(0, tr.voltage_bus_v, tr.current_bus_a,
                            ESC_TEMPERATURE_C + 273.15, round(tr.rpm), 0, esc_index)

    class PlantDroneCanEsc(SimDroneCanEsc):
        def _on_frame(self, frame: CanFrame) -> None:
            before = len(self.commands_seen)
            super()._on_frame(frame)
            if len(self.commands_seen) > before:
                plant.command_fraction(max(self.raw, 0) / dc.RAW_MAX)

    return PlantDroneCanEsc(link, node_id, esc_index, model,
                            status_period_s=status_period_s).start()


def start_vesc_uart(plant: WirePlant, pole_pairs: int):
    """A VESC on a pty (USB/UART packets); duty commands drive the plant, GET_VALUES
    reports its state; the firmware's 1 s command timeout reaches the motor."""
    from drivers.wire_sim.vesc import VescCommand, VescState
    from drivers.wire_sim.vesc_uart import SimVescUart

    def model(_t: float, _cmd: VescCommand) -> VescState:
        return _vesc_state(plant, pole_pairs)

    class PlantVescUart(SimVescUart):
        def applied(self, command: VescCommand) -> None:
            plant.command_fraction(_vesc_fraction(command))

        def _tick(self) -> bytes:
            released = self.timeouts
            out = super()._tick()
            if self.timeouts > released:  # the timeout released the motor
                plant.command_fraction(0.0)
            return out

    return PlantVescUart(model).start()


def start_kiss_esc(plant: WirePlant, pole_pairs: int, period_s: float):
    """An ESC streaming KISS telemetry on a pty: the plant's bus voltage, current, speed
    and the firmware's own consumption count."""
    from drivers.codecs import kiss
    from drivers.wire_sim.pty_sim import PtyStream

    used = {"mah": 0.0, "t": time.monotonic()}

    def next_frame() -> bytes:
        tr, now = plant.truth(), time.monotonic()
        used["mah"] += max(tr.current_bus_a, 0.0) * (now - used["t"]) / 3.6
        used["t"] = now
        return kiss.encode(kiss.Telemetry(ESC_TEMPERATURE_C, tr.voltage_bus_v,
                                          tr.current_bus_a, used["mah"], tr.rpm * pole_pairs))

    return PtyStream(next_frame, period_s).start()


SERIAL_PEERS: dict[str, Callable[..., Any]] = {
    "msp": start_msp_fc, "loadcell": start_loadcell_board, "vesc": start_vesc_uart,
    "kiss": start_kiss_esc}
CAN_PEERS: dict[str, Callable[..., Any]] = {"vesc": start_vesc, "dronecan": start_dronecan_esc}


# -- IMU-bench peers ------------------------------------------------------------------------------
class _PlantImu:
    """The IMU under test's readings on the FC's sensor loop (thread-safe): an MSP reply
    carries the loop's latest sample, taken ``clock_offset_s`` (the FC's sensor latency)
    before the request arrived; the model is the simulated IMU's own
    (``SimImuDevice.sample_at``), computed a block of loop samples at a time."""

    def __init__(self, sim: SimImuRig, clock: SimClock) -> None:
        self.sim, self.clock = sim, clock
        self.grid = GridSampler(self._readings, 1.0 / FC_LOOP_HZ,
                                block=round(_FC_BLOCK_S * FC_LOOP_HZ), version=self._motion)

    def _motion(self) -> tuple[int, tuple[float, float, float]]:
        hexapod = self.sim.hexapod
        return hexapod.motion_version, hexapod.pivot_m  # the lever arm is from the pivot

    def _readings(self, t: Any) -> Any:
        """acc, gyro and attitude of the samples taken at ``t`` (stamped an offset later)."""
        truth, gyro, acc = self.sim.imu.sample_at(t + self.sim.model.clock_offset_s)
        return np.hstack([acc, gyro, truth.euler_rad])

    def _sampled_at(self) -> float:
        return self.clock.now() - self.sim.model.clock_offset_s

    def __call__(self, _wall_t: float) -> tuple[Any, Any, Any]:
        alive = getattr(self.clock, "alive", None)
        if alive is not None:
            alive("msp")
        r = self.grid.at(self._sampled_at())
        return (r[0], r[1], r[2]), (r[3], r[4], r[5]), (r[6], r[7], r[8])

    def prefetch(self) -> bytes:
        """Between requests (the FC's port tick): the next block before a reply needs it."""
        self.grid.prefetch(self._sampled_at())
        return b""


def start_msp_peer(sim: SimImuRig, clock: SimClock, *, variant: str = "BTFL",
                   acc_1g: int = BTFL_ACC_1G) -> Any:
    """A Betaflight- (or INAV-) like FC on a pty answering from the plant's IMU model."""
    from drivers.wire_sim.msp_fc import SimFlightController

    class PlantFc(SimFlightController):
        def _reply(self, m: msp.MspMessage) -> bytes:
            if isinstance(m, msp.Request) and m.cmd == msp.MSP_FC_VARIANT:
                return msp.encode_message(msp.FcVariant(variant))
            return super()._reply(m)

    gyro_lsb = 1.0 if variant == "INAV" else msp.BTFL_GYRO_LSB_PER_DPS
    imu = _PlantImu(sim, clock)
    fc = PlantFc(imu, acc_1g=acc_1g, gyro_lsb_per_dps=gyro_lsb, rtc_clock=clock.now,
                 multiple=variant != "INAV")
    fc.port.tick = imu.prefetch
    return fc.start()


def start_gx3_peer(sim: SimImuRig, clock: SimClock) -> Any:
    """A 3DM-GX3-25 on a pty; its timer and its stream run on the plant's clock."""
    from scipy.spatial.transform import Rotation

    from drivers.wire_sim.gx3 import SimGx3

    ref = sim.reference_imu
    period = 1.0 / ref.rate_hz
    alive = getattr(clock, "alive", None)
    lock = threading.Lock()

    def readings(t: Any) -> Any:
        """Body rates and attitude (each with the reference's noise) at times ``t``."""
        with lock:
            s = sim.hexapod.state_at(t)
            n = len(s.t_s)
            att = Rotation.from_euler("xyz", s.euler_rad) * Rotation.from_rotvec(
                ref.rng.normal(0.0, ref.attitude_noise_rad, (n, 3)))
            rate = s.omega_b_rad_s + ref.rng.normal(0.0, ref.gyro_noise_rad_s, (n, 3))
        return np.hstack([rate, att.as_euler("xyz")])

    def motion() -> int:
        return sim.hexapod.motion_version

    class PlantGx3(SimGx3):
        grid: GridSampler | None = None  # the stream's timer grid, from its start
        k_next = 0  # the stream's next packet on it

        def _packet(self, cmd: int, t: float | None = None) -> bytes:
            """The packet of the sample taken at ``t`` (default now), timer included."""
            if cmd != gx3.EULER_RATES:
                return super()._packet(cmd)
            t = clock.now() if t is None else t
            return self._euler_rates(t, readings(np.array([t]))[0].tolist())

        @staticmethod
        def _euler_rates(t: float, row: list[float]) -> bytes:
            ticks = round(t * gx3.TICKS_PER_SECOND) & 0xFFFFFFFF
            return gx3.encode_reply(gx3.EulerRates(ticks, row[3], row[4], row[5],
                                                   (row[0], row[1], row[2])))

        def handle(self, data: bytes) -> bytes:
            seen = len(self.requests)
            out = super().handle(data)
            if any(r[0] == gx3.SET_CONTINUOUS for r in self.requests[seen:]):
                # the stream starts now, on the plant clock
                self.grid = GridSampler(readings, period, origin_s=clock.now(),
                                        block=_GX3_BLOCK, version=motion)
                self.k_next = 0
            return out

        def tick(self) -> bytes:
            """Every packet due on the plant clock (a late wakeup sends the backlog), then
            the stream's next readings computed before they are due."""
            grid = self.grid
            if self.stream_cmd is None or grid is None:
                return b""
            if alive is not None:
                alive("gx3")
            out = bytearray()
            now = clock.now()
            for _ in range(_MAX_BURST):  # a starved thread writes what it has, then goes on
                t = grid.time_of(self.k_next)
                if now < t:
                    break
                row = grid.row(self.k_next)
                if self.stream_cmd == gx3.EULER_RATES:
                    out += self._euler_rates(t, row)
                else:
                    out += super()._packet(self.stream_cmd)
                self.k_next += 1
            grid.prefetch(now)
            return bytes(out)

    def sample_now(_t: float) -> tuple[Any, Any, Any]:
        """What a polled packet other than EULER_RATES reads (no accelerometer)."""
        row = readings(np.array([clock.now()]))[0].tolist()
        return (0.0, 0.0, 0.0), tuple(row[:3]), tuple(row[3:])

    peer = PlantGx3(sample_now, period_s=period)
    # wake every 2 ms of wall time at most (fewer wakeups: less GIL traffic for the host)
    peer.port.tick_s = min(0.002, period / getattr(clock, "time_scale", 1.0) / 2)
    return peer.start()
