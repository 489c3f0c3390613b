"""``msp+tcp://127.0.0.1:5761`` with ``launch = "betaflight-sitl"``: the bench runs the firmware.

The ESC role is then the real Betaflight 4.6.0 SITL's motor test, started by the bench for
the run: the firmware as a child process (``drivers.backends.betaflight_sitl``), the rig's
simulated plant as its vehicle (``drivers.wire_sim.sitl_plant``: FDM in, motor output
to the plant's ESC) and the MSP client on its TCP port, as with any ``msp+tcp://`` FC.
The sensors are the wire-level simulated ones (``serial://sim/loadcell``...) on the same
plant. The ESC comes wrapped in :class:`drivers.command_delay.OutputTimedEsc`, which
times each command to the firmware's output for ``run.json``.

Closing order (the rig's ``close()``): the ESC sends every motor to 1000, the MSP
connection closes, then the plant's owner stops the peer (after the idle output reached
the plant) and the firmware (SIGTERM, then SIGKILL), whatever happened before.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any

from drivers.contracts import Esc
from drivers.device_options import DeviceUrl
from drivers.errors import DeviceError
from drivers.registry import backend

__all__ = ["LAUNCHERS", "open_sitl_esc"]

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

    spec.text("launch", choices=LAUNCHERS)
    if spec.host not in LOOPBACK:
        raise spec.fail("launch", f"the launched firmware listens on this machine: use "
                                  f"msp+tcp://127.0.0.1:5761, not host {spec.host!r}")
    binary_opt = spec.raw("sitl_binary", "")
    if not isinstance(binary_opt, str):
        raise spec.fail("sitl_binary", f"expected a path, got {binary_opt!r}")
    rate_hz = spec.number("fdm_rate_hz", 250.0, lo=100.0, hi=1000.0)
    motor = spec.integer("motor", 0, lo=0, hi=3)  # the SITL drives 4 motors
    launcher = backend("betaflight_sitl", spec)
    binary = launcher.find_binary(binary_opt or None)  # before anything starts
    wire = ctx.world()  # the rig's plant; its owner stops what is added below, last
    ctx.wire = wire
    firmware, port, peer = _launch(ctx, spec, launcher, binary, wire.plant, motor, rate_hz)
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


def _launch(ctx: Any, spec: DeviceUrl, launcher: Any, binary: Any, plant: Any, motor: int,
            rate_hz: float) -> tuple[Any, Any, Any]:
    """A firmware that answers MSP and sends motor output, with its connected MSP port
    and its running plant peer; relaunched up to ``LAUNCHES`` times.

    Why: the MSP port opens while the firmware is still initialising (the first reply
    took up to 0.4 s), and about one launch in ten never ran its gyro task (MSP_STATUS
    cycle time 0, so no motor output at all), more often when FDM arrived before the
    first MSP reply. So: MSP first, then FDM, then the first motor update, or relaunch
    (Betaflight's own SITL harness also relaunches, up to 3 times)."""
    from drivers.backends.msp_fc import MspClient
    from drivers.wire_sim.sitl_plant import SitlPlantPeer

    mt = backend("msp_tcp", spec)
    for attempt in range(1, LAUNCHES + 1):
        firmware = port = peer = None
        try:
            firmware = launcher.SitlProcess.launch(binary)
            port = mt.open_port("127.0.0.1", spec.port or mt.DEFAULT_PORT, spec.url,
                                connect_timeout_s=ctx.open_timeout_s)
            client = MspClient(port, spec.url, timeout_s=READY_S)
            client.identify()
            launcher.await_control_loop(client, spec.url, READY_S)
            peer = SitlPlantPeer(plant, motor, rate_hz=rate_hz).start()
            peer.wait_output(FIRST_OUTPUT_S)
            return firmware, port, peer
        except BaseException as exc:
            if peer is not None:
                peer.stop()
            if port is not None:
                port.close()
            if firmware is not None:
                firmware.stop()
            # a firmware that exits at start or never opens its port would do so again;
            # one that lost its port to a lingering connection or ran no control loop not
            retry = isinstance(exc, launcher.PortBusy) or (
                firmware is not None and isinstance(exc, DeviceError))
            if not retry or attempt == LAUNCHES:
                raise
            log.info("Betaflight SITL launch %d of %d not usable (%s): relaunching",
                     attempt, LAUNCHES, exc)
            time.sleep(RELAUNCH_PAUSE_S)  # a connection of the last one may still linger
    raise AssertionError("unreachable")

