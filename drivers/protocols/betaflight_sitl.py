"""``msp+tcp://127.0.0.1:5761`` with ``launch = "betaflight-sitl"``: the bench runs the firmware.

The ESC role is then the real Betaflight 4.6.0 SITL's motor test, started by the bench for
the run: the firmware as a child process (``drivers.backends.betaflight_sitl``), the rig's
simulated plant as its vehicle (``drivers.wire_sim.sitl_plant``: FDM in, motor output
to the plant's ESC; run by the plant's world process, with the simulated sensors) and
the MSP client on its TCP port, as with any ``msp+tcp://`` FC.
The sensors are the wire-level simulated ones (``serial://sim/loadcell``...) on the same
plant. The ESC comes wrapped in :class:`drivers.command_delay.OutputTimedEsc`, which
times each command to the firmware's output for ``run.json``.

On the IMU bench the firmware is the IMU under test instead (:func:`open_sitl_imu`): the
same launch, its FDM made from the simulated hexapod and the rig's IMU model
(``drivers.wire_sim.sitl_imu_world``), its RAW_IMU (and ATTITUDE) polled over MSP as any
flight controller's. The world runs on the wall clock (a paced clock at time scale 1):
the firmware's clock follows the packets' stamps, and its filters and its 100 Hz MSP
task are real-time things.

Closing order (the rig's ``close()``): the ESC sends every motor to 1000, the MSP
connection closes, then the plant's owner stops the peer (after the idle output reached
the plant) and the firmware (SIGTERM, then SIGKILL), whatever happened before.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any

from drivers.contracts import Esc, Sensor
from drivers.device_options import DeviceUrl
from drivers.errors import DeviceError
from drivers.registry import backend

__all__ = ["LAUNCHERS", "open_sitl_esc", "open_sitl_imu"]

LAUNCHERS = ("betaflight-sitl",)
LOOPBACK = ("127.0.0.1", "localhost")
FIRST_OUTPUT_S = 1.0  # first FDM packet to first motor update (measured 10-40 ms)
READY_S = 3.0  # MSP port open to the first MSP reply (measured 0.02-0.4 s)
LAUNCHES = 3
RELAUNCH_PAUSE_S = 0.5

log = logging.getLogger(__name__)


def open_sitl_esc(ctx: Any, spec: DeviceUrl, share_link: Callable[[Any], Any]) -> Esc:
    """Launch the firmware and its plant peer, then open the motor test over MSP;
    ``share_link(port)`` makes the connected port the rig's link to the firmware."""
    from drivers.backends.msp_rc_esc import MspRcEsc
    from drivers.command_delay import OutputTimedEsc
    from drivers.protocols.serial import open_msp_esc

    launcher, binary, rate_hz = _launch_options(spec)
    motor = spec.integer("motor", 0, lo=0, hi=3)  # the SITL drives 4 motors
    wire = ctx.world()  # the rig's plant; its owner stops what is added below, last
    ctx.wire = wire
    firmware, port, peer = _launch(ctx, spec, launcher, binary,
                                   lambda: wire.sitl_peer(motor, rate_hz))  # in its process
    wire.add("sitl:firmware", firmware, firmware.stop)
    wire.add("sitl:plant", peer, peer.stop)  # stopped before the firmware
    ctx.peers[spec.role] = peer
    esc = open_msp_esc(ctx, spec, lambda _motor: share_link(port))
    ctx.answers[spec.role] += (f"; Betaflight SITL launched by the bench (pid "
                               f"{firmware.proc.pid}, MSP port open after "
                               f"{firmware.started_s:.2f} s), FDM at {rate_hz:g} Hz")
    if isinstance(esc, MspRcEsc):
        return esc  # the RC path maps the command onto the throttle: no value to match
    return OutputTimedEsc(esc, peer, "Betaflight SITL")


def open_sitl_imu(ctx: Any, spec: DeviceUrl, share_link: Callable[[Any], Any]) -> Sensor:
    """Launch the firmware fed by the IMU bench's simulated world, then poll its RAW_IMU
    (and ATTITUDE, option ``attitude``) over MSP as the IMU under test."""
    from drivers.backends.msp_fc import STALE_GAP_S, MspClient, MspImuSensor
    from drivers.backends.msp_pipeline import PipelinedMspImu
    from drivers.codecs.sitl import SITL_ACC_1G, SITL_GYRO_LSB_PER_DPS
    from drivers.wire_sim.sitl_imu_world import HexapodFdm
    from drivers.wire_sim.sitl_plant import SitlPlantPeer

    launcher, binary, fdm_hz = _launch_options(spec)
    # the firmware's own scales unless the rig file says otherwise (what a run proves)
    acc_1g = spec.number("acc_1g", SITL_ACC_1G, lo=1.0, hi=32768.0)
    gyro_lsb = spec.number("gyro_lsb_per_dps", SITL_GYRO_LSB_PER_DPS, lo=1e-3, hi=1e3)
    rate_hz = spec.number("rate_hz", ctx.rig.imu.value("rate_hz"), lo=0.1, hi=500.0)
    timeout_s = spec.number("timeout_s", 1.0, lo=0.005, hi=5.0)
    # rows whose MSP round trip was longer, or polled further from an FDM packet the
    # firmware accepted, are dropped: when the firmware read its sensors is known to no
    # better (docs/sim-rig.md, "Real firmware as the IMU")
    max_rt = spec.number("max_round_trip_s", timeout_s, lo=0.001, hi=timeout_s)
    stale_gap = spec.number("stale_gap_s", STALE_GAP_S, lo=0.001, hi=1.0)
    attitude = spec.raw("attitude", False)
    if not isinstance(attitude, bool):
        raise spec.fail("attitude", f"expected true or false, got {attitude!r}")
    world = ctx.world()
    scale = getattr(world.clock, "time_scale", None)
    if scale != 1.0:
        raise spec.fail("launch", "the launched firmware runs on the wall clock: the IMU "
                                  "bench's world must too (time_scale 1)")
    firmware, port, peer = _launch(ctx, spec, launcher, binary, lambda: SitlPlantPeer(
        None, 0, rate_hz=fdm_hz, fdm=HexapodFdm(world, 1.0 / fdm_hz), clock=ctx.clock.now))
    ctx.on_close(firmware.stop)
    ctx.on_close(peer.stop)  # closers run last-in first-out: the feeder stops first
    ctx.peers[spec.role] = peer
    link = share_link(port)
    client = MspClient(link, spec.url, timeout_s=timeout_s)
    imu = PipelinedMspImu(client, rate_hz=rate_hz, acc_1g=acc_1g, clock=ctx.clock, url=spec.url,
                 attitude=attitude, gyro_lsb_per_dps=gyro_lsb, multiple=True,
                 max_round_trip_s=max_rt)
    ctx.answers[spec.role] = (f"flight controller {imu.variant}, MSP API {imu.api.api_major}."
                              f"{imu.api.api_minor}; Betaflight SITL launched by the bench (pid "
                              f"{firmware.proc.pid}), fed the hexapod world at {fdm_hz:g} Hz")
    return MspImuSensor(imu, rate_hz, port=link, peer=peer, attitude=attitude,
                        stale_gap_s=stale_gap)


def _launch_options(spec: DeviceUrl) -> tuple[Any, Any, float]:
    """The launcher module, the binary (found before anything starts) and the FDM rate."""
    spec.text("launch", choices=LAUNCHERS)
    if spec.host not in LOOPBACK:
        raise spec.fail("launch", f"the launched firmware listens on this machine: use "
                                  f"msp+tcp://127.0.0.1:5761, not host {spec.host!r}")
    binary_opt = spec.raw("sitl_binary", "")
    if not isinstance(binary_opt, str):
        raise spec.fail("sitl_binary", f"expected a path, got {binary_opt!r}")
    rate_hz = spec.number("fdm_rate_hz", 250.0, lo=100.0, hi=1000.0)
    launcher = backend("betaflight_sitl", spec)
    return launcher, launcher.find_binary(binary_opt or None), rate_hz


def _settings(spec: DeviceUrl) -> dict[str, str | int]:
    """Option ``cli_settings``: the firmware's own settings for the run (CLI names and
    values, e.g. ``{ acc_lpf_hz = 0 }``), given at launch before any MSP traffic
    (``drivers.backends.betaflight_sitl``)."""
    settings = spec.raw("cli_settings", {})
    if not isinstance(settings, dict) or not all(
            isinstance(k, str) and isinstance(v, str | int) for k, v in settings.items()):
        raise spec.fail("cli_settings", f"expected a table of setting names and values, "
                                        f"got {settings!r}")
    return settings


def _launch(ctx: Any, spec: DeviceUrl, launcher: Any, binary: Any,
            make_peer: Callable[[], Any]) -> tuple[Any, Any, Any]:
    """A firmware that answers MSP and sends motor output, with its connected MSP port
    and its running plant peer; relaunched up to ``LAUNCHES`` times.

    Why: the MSP port opens while the firmware is still initialising (the first reply
    took up to 0.4 s), and about one launch in ten never ran its gyro task (MSP_STATUS
    cycle time 0, so no motor output at all), more often when FDM arrived before the
    first MSP reply. So: MSP first, then FDM, then the first motor update, or relaunch
    (Betaflight's own SITL harness also relaunches, up to 3 times)."""
    from drivers.backends.msp_fc import MspClient

    mt = backend("msp_tcp", spec)
    for attempt in range(1, LAUNCHES + 1):
        firmware = port = peer = None
        try:
            firmware = launcher.SitlProcess.launch(binary, settings=_settings(spec))
            port = mt.open_port("127.0.0.1", spec.port or mt.DEFAULT_PORT, spec.url,
                                connect_timeout_s=ctx.open_timeout_s)
            client = MspClient(port, spec.url, timeout_s=READY_S)
            client.identify()
            launcher.await_control_loop(client, spec.url, READY_S)
            peer = make_peer().start()
            peer.wait_output(FIRST_OUTPUT_S)
            return firmware, port, peer
        except BaseException as exc:
            if peer is not None:
                peer.stop()
            if port is not None:
                port.close()
            if firmware is not None:
                firmware.stop()
            # a firmware that exits at start or never opens its port would do so again
            # (one that lost its port to a lingering connection the launch tried again);
            # one that ran no control loop not
            retry = firmware is not None and isinstance(exc, DeviceError)
            if not retry or attempt == LAUNCHES:
                raise
            log.info("Betaflight SITL launch %d of %d not usable (%s): relaunching",
                     attempt, LAUNCHES, exc)
            time.sleep(RELAUNCH_PAUSE_S)  # a connection of the last one may still linger
    raise AssertionError("unreachable")

