"""Registry entry of the PI GCS hexapod controller: ``tcp://host[:50000]``.

Limits and log rate come from the rig file; ``timeout_s``, ``start_tolerance``,
``derivative_window`` and the GCS dialect options from the device's options. The host
``sim`` (``tcp://sim[:port]``) starts the simulated PI controller
(``drivers.wire_sim.pi_hexapod``) on loopback, driven by the simulated IMU bench's hexapod
plant (in the world's process when it has one: ``drivers.wire_sim.imu_world``), and
connects the real backend to it.
"""

from __future__ import annotations

from typing import Any
from urllib.parse import urlsplit

from drivers.contracts import Hexapod
from drivers.device_options import DeviceUrl
from drivers.errors import DeviceError
from drivers.registry import register
from drivers.rig_view import RigView, section


def open_pi_hexapod(rig: RigView, url: str, options: dict[str, Any], clock: Any,
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

    hexapod = section(rig, rig.hexapod, "hexapod")
    limits, log_rate_hz = hexapod.hexapod_limits(), hexapod.log_rate_hz
    return PiHexapod(connect(), url=url, timeout_s=timeout_s, connect=connect, limits=limits,
                     clock=clock, log_rate_hz=log_rate_hz, dialect=dialect,
                     start_tolerance=tolerance, derivative_window=window)


@register("tcp", None, ("hexapod",), summary="the PI GCS hexapod of the IMU bench",
          example="tcp://<host>[:port]")
def pi_hexapod(ctx: Any, spec: DeviceUrl) -> Hexapod:
    options = {k: spec.raw(k) for k in spec.options}  # GcsDialect refuses unknown keys
    timeout_s = ctx.open_timeout_s
    if not spec.is_wire_sim:
        return open_pi_hexapod(ctx.rig, spec.url, options, ctx.clock, timeout_s)
    from drivers.wire_sim.imu_world import start_imu_device

    try:
        wire = start_imu_device(ctx, "tcp:sim", "hexapod", spec.port or 0)
    except DeviceError as exc:
        raise DeviceError(f"hexapod: {spec.url!r}: {exc}") from None
    ctx.wire = wire
    host, port = wire.address
    hexapod = open_pi_hexapod(ctx.rig, f"tcp://{host}:{port}", options, ctx.clock, timeout_s)
    hold = getattr(ctx.clock, "hold", None)
    if hold is not None:  # a paced clock: uploads take no simulated time (HeldUploads)
        from drivers.wire_sim.paced_clock import HeldUploads

        return HeldUploads(hexapod, ctx.clock)  # type: ignore[return-value]
    return hexapod
