"""Registry entries of simulated (``sim://<role>``) and recorded (``replay://``) devices.

``sim://`` devices are the rig's simulated world itself (``drivers.sim_worlds``: the
propulsion ``SimRig`` or the IMU bench's ``SimImuRig``, on their fast simulated clock);
the rig file may schedule faults on them. ``replay:///abs/path/file.npz`` sensors hand out
a recording as the rig clock passes its time stamps.
"""

from __future__ import annotations

from typing import Any

from drivers.device_options import DeviceUrl
from drivers.registry import register
from drivers.sim_worlds import sim_faults

ALL_ROLES = ("esc", "load_cell", "power", "rpm", "hexapod", "imu", "reference_imu")


@register("sim", None, ALL_ROLES, summary="the simulated devices", example="sim://{role}")
def simulated(ctx: Any, spec: DeviceUrl) -> Any:
    """The role's device of the simulated world, with the faults the rig file schedules."""
    device = getattr(ctx.world(), spec.role)
    sim_faults(device, {k: spec.raw(k) for k in spec.options}, spec.role)
    return device


@register("replay", None, ("load_cell", "power", "rpm"), summary="recorded sensor data",
          example="replay:///<file>.npz")
def replay(ctx: Any, spec: DeviceUrl) -> Any:
    from drivers.replay import ReplaySensor

    return ReplaySensor.from_url(spec.url, ctx.clock)
