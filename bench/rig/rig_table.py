"""Reading rig files (propulsion and IMU bench): TOML tables that name file and field.

Both benches' rig sections (:mod:`bench.rig.rig_propulsion`, :mod:`bench.rig.rig_imu`) check
every value through a :class:`RigTable`, so a bad value raises ``RigError`` naming the
file, the table, the key and what was expected.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any, overload

from bench.errors import RigError

__all__ = ["RigTable", "read_rig_toml"]


class RigTable:
    """A TOML table with its location, for error messages that name file and field."""

    def __init__(self, path: Path, where: str, data: Any) -> None:
        self.path, self.where = path, where
        if not isinstance(data, dict):
            self.fail("", f"expected a table, got {type(data).__name__}")
        self.data: dict[str, Any] = data

    def fail(self, key: str, msg: str) -> RigError:
        """Raise the RigError for ``key`` of this table (return type eases type checking)."""
        where = f"[{self.where}] " if self.where else ""
        raise RigError(f"{self.path}: {where}{key}: {msg}".replace(" : ", ": "))

    def only(self, *allowed: str) -> None:
        for key in self.data:
            if key not in allowed:
                self.fail(key, f"unknown key; expected one of {', '.join(allowed)}")

    def table(self, key: str, required: bool = True) -> RigTable | None:
        if key not in self.data:
            if required:
                self.fail(key, "missing table")
            return None
        return RigTable(self.path, f"{self.where}.{key}" if self.where else key, self.data[key])

    def text(self, key: str, default: str | None = None) -> str:
        if key not in self.data:
            if default is None:
                self.fail(key, "missing; expected a string")
            return default  # type: ignore[return-value]
        value = self.data[key]
        if not isinstance(value, str) or not value.strip():
            self.fail(key, f"expected a non-empty string, got {value!r}")
        return value

    @overload
    def number(self, key: str, default: float, *, required: bool = False,
               lo: float = -math.inf, hi: float = math.inf, unit: str = "") -> float: ...
    @overload
    def number(self, key: str, default: None = None, *, required: bool = False,
               lo: float = -math.inf, hi: float = math.inf, unit: str = "") -> float | None: ...
    def number(self, key: str, default: float | None = None, *, required: bool = False,
               lo: float = -math.inf, hi: float = math.inf, unit: str = "") -> float | None:
        """The number at ``key`` within [lo, hi], or ``default`` when it is absent (so a
        number default gives a number)."""
        if key not in self.data:
            if required:
                self.fail(key, f"missing; expected a number{' in ' + unit if unit else ''}")
            return default
        value = self.data[key]
        is_number = isinstance(value, int | float) and not isinstance(value, bool)
        if not is_number or not math.isfinite(value):
            self.fail(key, f"expected a number, got {value!r}")
        if not lo <= value <= hi:
            self.fail(key, f"{value} {unit}".rstrip() + f" outside {lo:g}-{hi:g} {unit}".rstrip())
        return float(value)

    def flag(self, key: str, default: bool) -> bool:
        value = self.data.get(key, default)
        if not isinstance(value, bool):
            self.fail(key, f"expected true or false, got {value!r}")
        return value


def read_rig_toml(path: Path) -> dict[str, Any]:
    """The TOML of a rig file; unreadable or invalid files raise ``RigError``."""
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise RigError(f"{path}: rig file not found") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:  # bytes that are not text
        raise RigError(f"{path}: not valid TOML: {exc}") from None
    except OSError as exc:
        raise RigError(f"{path}: cannot read rig file: {exc}") from None
