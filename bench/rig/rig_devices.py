"""The devices of a rig file, whatever the bench: one table per role with its URL.

Every bench names its devices the same way (``[devices.<role>] url = ...`` with options),
so both benches' rig sections (:mod:`bench.rig.rig_propulsion`, :mod:`bench.rig.rig_imu`) parse
them here; only which keys a device may have and how a simulated device must be named
differ per bench.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import urlsplit

from bench.rig.rig_table import RigTable

__all__ = ["URL_SCHEMES", "DeviceConfig", "parse_device"]

URL_SCHEMES = ("sim", "replay", "serial", "can", "nidaq", "tcp", "msp+tcp")


@dataclass(frozen=True)
class DeviceConfig:
    """One device: where it is (URL), which channel, its calibration and extra options."""

    url: str
    channel: str = ""
    calibration: Mapping[str, float] = field(default_factory=dict)
    options: Mapping[str, Any] = field(default_factory=dict)

    @property
    def scheme(self) -> str:
        return urlsplit(self.url).scheme


def parse_device(top: RigTable, role: str, *, keys: tuple[str, ...],
                 scheme_of: Callable[[str], str],
                 sim_problem: Callable[[str], str | None]) -> DeviceConfig:
    """``[devices.<role>]``: ``url`` with a known scheme, the bench's other ``keys``
    (``channel``, ``calibration``, ``options``); ``sim_problem(url)`` says what is wrong
    with a ``sim://`` URL for this role (None: nothing)."""
    t = top.table(role)
    assert t is not None
    t.only("url", *keys)
    url = t.text("url")
    scheme = scheme_of(url)
    if scheme not in URL_SCHEMES:
        t.fail("url", f"{url!r}: unknown scheme {scheme!r}; expected one of "
                      + ", ".join(f"{s}://" for s in URL_SCHEMES))
    problem = sim_problem(url) if scheme == "sim" else None
    if problem is not None:
        t.fail("url", problem)
    channel = t.text("channel", "") if "channel" in keys else ""
    calibration: dict[str, float] = {}
    cal = t.table("calibration", required=False) if "calibration" in keys else None
    if cal is not None:
        for key in cal.data:
            calibration[key] = cal.number(key)  # type: ignore[assignment]
    opts = t.table("options", required=False)
    options: Mapping[str, Any] = dict(opts.data) if opts else {}
    return DeviceConfig(url, channel, calibration, options)
