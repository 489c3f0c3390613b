"""A rig device's URL and options, checked key by key for the backend that will serve it.

Options come from the URL's query (``serial:///dev/ttyUSB0?baud=115200&protocol=msp``,
strings) and from the device's ``options`` table in the rig file (TOML types); a key
given both ways must agree. Every problem raises ``DeviceError`` naming the rig file,
the device table and the key, and unknown keys are refused (a typo must not be ignored).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import parse_qsl, urlsplit

from drivers.errors import DeviceError
from drivers.rig_view import DeviceView

__all__ = ["DeviceUrl", "parse_device"]


@dataclass
class DeviceUrl:
    """One rig device: role, URL parts and the merged options (read through the getters)."""

    rig_path: str
    role: str
    url: str
    scheme: str
    host: str
    path: str
    port: int | None
    options: dict[str, Any]
    channel: str = ""
    calibration: Mapping[str, float] = field(default_factory=dict)
    _used: set[str] = field(default_factory=set)

    @property
    def where(self) -> str:
        return f"{self.rig_path}: [devices.{self.role}]"

    def fail(self, key: str, msg: str) -> DeviceError:
        what = f"options.{key}" if key else f"url {self.url!r}"
        return DeviceError(f"{self.where} {what}: {msg}")

    @property
    def is_wire_sim(self) -> bool:
        """``serial://sim/...``, ``can://sim/...``: the simulated peer on a local transport."""
        return self.host == "sim"

    # -- getters -------------------------------------------------------------------------
    def has(self, key: str) -> bool:
        return key in self.options

    def raw(self, key: str, default: Any = None) -> Any:
        self._used.add(key)
        return self.options.get(key, default)

    def text(self, key: str, default: str | None = None, choices: tuple[str, ...] = ()) -> str:
        value = self.raw(key, default)
        if value is None:
            raise self.fail(key, "missing" + (f"; expected one of {', '.join(choices)}"
                                              if choices else "; expected a string"))
        if not isinstance(value, str) or not value:
            raise self.fail(key, f"expected a non-empty string, got {value!r}")
        if choices and value not in choices:
            raise self.fail(key, f"{value!r}: expected one of {', '.join(choices)}")
        return value

    def number(self, key: str, default: float | None = None, *, lo: float = -math.inf,
               hi: float = math.inf) -> float:
        value = self.raw(key, default)
        if value is None:
            raise self.fail(key, "missing; expected a number")
        if isinstance(value, str):
            try:
                value = float(value)
            except ValueError:
                raise self.fail(key, f"expected a number, got {value!r}") from None
        if isinstance(value, bool) or not isinstance(value, int | float) \
                or not math.isfinite(value):
            raise self.fail(key, f"expected a number, got {value!r}")
        if not lo <= value <= hi:
            raise self.fail(key, f"{value:g} outside {lo:g}..{hi:g}")
        return float(value)

    def integer(self, key: str, default: int | None = None, *, lo: int = 0,
                hi: int = 2**31) -> int:
        value = self.number(key, default, lo=lo, hi=hi)
        if value != int(value):
            raise self.fail(key, f"expected a whole number, got {value:g}")
        return int(value)

    def flag(self, key: str, default: bool = False) -> bool:
        value = self.raw(key, default)
        if not isinstance(value, bool):
            raise self.fail(key, f"expected true or false, got {value!r}")
        return value

    def names(self, key: str, default: tuple[str, ...]) -> tuple[str, ...]:
        value = self.raw(key, None)
        if value is None:
            return default
        if isinstance(value, str):
            value = [v for v in value.split(",") if v]
        if not isinstance(value, list | tuple) or not value or \
                not all(isinstance(v, str) and v for v in value):
            raise self.fail(key, f"expected a list of column names, got {value!r}")
        return tuple(value)

    def check_used(self) -> None:
        """Refuse keys no backend asked for (typos, options of another protocol)."""
        unknown = sorted(set(self.options) - self._used)
        if unknown:
            allowed = ", ".join(sorted(self._used)) or "none"
            raise self.fail(unknown[0], f"unknown option for this device (known: {allowed})")

    def device_options(self, exclude: tuple[str, ...] = ()) -> dict[str, Any]:
        return {k: v for k, v in self.options.items() if k not in exclude}


def parse_device(rig_path: str | os.PathLike[str], role: str, dev: DeviceView) -> DeviceUrl:
    """Split ``dev.url`` and merge its query with ``dev.options`` (a rig's DeviceConfig)."""
    url = str(dev.url)
    parts = urlsplit(url)
    options: dict[str, Any] = {}
    where = f"{rig_path}: [devices.{role}]"
    for key, value in parse_qsl(parts.query, keep_blank_values=True):
        if key in options:
            raise DeviceError(f"{where} url {url!r}: query key {key!r} given twice")
        options[key] = value
    for key, value in dict(getattr(dev, "options", {}) or {}).items():
        if key in options and str(options[key]) != str(value):
            raise DeviceError(f"{where} options.{key}: {value!r} disagrees with the URL's "
                              f"{key}={options[key]}")
        options[key] = value
    try:
        port = parts.port
    except ValueError:
        raise DeviceError(f"{where} url {url!r}: bad port number") from None
    return DeviceUrl(str(rig_path), role, url, parts.scheme, parts.hostname or "",
                     parts.path, port, options, str(getattr(dev, "channel", "") or ""),
                     dict(getattr(dev, "calibration", {}) or {}))
