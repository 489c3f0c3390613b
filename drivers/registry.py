"""The protocol registry: (URL scheme, ``protocol`` option, role) -> the function that opens it.

A protocol is a codec (``drivers/codecs``, pure bytes <-> messages), a backend
(``drivers/backends``, the codec over a port, bus or task, filling a device contract) and
one entry here, written next to its siblings in ``drivers/protocols/<scheme>.py``::

    @register("serial", "kiss", roles=("power", "rpm"))
    def kiss_telemetry(ctx: DeviceContext, spec: DeviceUrl) -> Sensor: ...

Opening a device is a lookup (:func:`lookup`), not a switch: adding a protocol touches its
codec, its backend and its entry, nothing else. Backends are imported by the entries through
:func:`backend`, lazily, so a missing optional library (pyserial, python-can, nidaqmx) is a
``DeviceError`` naming the device and the package, not an import failure at start-up.
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from drivers.device_options import DeviceUrl
from drivers.errors import DeviceError

__all__ = ["Entry", "backend", "entries", "lookup", "register", "schemes"]

Opener = Callable[[Any, DeviceUrl], Any]  # (DeviceContext, spec) -> the opened device

# the optional vendor libraries (module -> the package to install); a backend imports one
_PACKAGES = {"serial": "pyserial", "can": "python-can", "nidaqmx": "nidaqmx"}
_VERB = {"esc": "drive an ESC", "hexapod": "move the hexapod"}


@dataclass(frozen=True)
class Entry:
    """One protocol on one transport: which roles it serves and how to open it."""

    scheme: str
    protocol: str | None  # None: the scheme has no protocol option (nidaq://, tcp://)
    roles: tuple[str, ...]
    open: Opener
    summary: str  # a few words for error messages: what this scheme/protocol is
    example: str  # the URL form for error messages; ``{role}`` is filled in


_TABLE: list[Entry] = []
_DEFAULTS: dict[tuple[str, str], str] = {}  # (scheme, role) -> protocol when none is given


def register(scheme: str, protocol: str | None, roles: tuple[str, ...], *, summary: str,
             example: str, default_for: tuple[str, ...] = ()) -> Callable[[Opener], Opener]:
    """Decorator: ``fn(ctx, spec)`` opens ``protocol`` on ``scheme://`` for ``roles``.

    ``default_for``: roles for which this protocol is used when the rig file names none.
    The entry modules (``drivers.protocols``) are imported by ``drivers.device_context``,
    so every entry is in the table before the first lookup.
    """
    def add(fn: Opener) -> Opener:
        for e in _TABLE:
            if e.scheme == scheme and e.protocol == protocol and set(e.roles) & set(roles):
                raise ValueError(f"{scheme}://{protocol} registered twice for {roles}")
        _TABLE.append(Entry(scheme, protocol, tuple(roles), fn, summary, example))
        for role in default_for:
            _DEFAULTS[(scheme, role)] = str(protocol)
        return fn

    return add


def entries(scheme: str | None = None) -> list[Entry]:
    """Registered entries (all, or one scheme's), in registration order."""
    return [e for e in _TABLE if scheme is None or e.scheme == scheme]


def schemes() -> tuple[str, ...]:
    return tuple(dict.fromkeys(e.scheme for e in entries()))


def _protocols(scheme: str) -> tuple[str, ...]:
    return tuple(dict.fromkeys(e.protocol for e in entries(scheme) if e.protocol))


def _alternatives(role: str) -> str:
    """How a rig file may name a device for ``role`` (for error messages)."""
    out = []
    for scheme in sorted(schemes(), key=lambda s: s != "sim"):  # the simulator first
        fits = [e for e in entries(scheme) if role in e.roles]
        if not fits:
            continue
        url = fits[0].example.format(role=role.replace("_", "-"))
        protos = [str(e.protocol) for e in fits if e.protocol]
        out.append(url + (f" (protocol {' or '.join(protos)})" if protos else ""))
    return " or ".join(out) or "nothing"


def lookup(spec: DeviceUrl) -> Entry:
    """The entry that opens ``spec`` (its scheme, protocol option and role).

    Raises ``DeviceError`` naming the rig file, the device table and what was expected.
    """
    on_scheme = entries(spec.scheme)
    if not on_scheme:
        raise spec.fail("", f"unknown device URL scheme {spec.scheme!r}")
    fits = [e for e in on_scheme if spec.role in e.roles]
    if not fits:
        what = ", ".join(dict.fromkeys(e.summary for e in on_scheme))
        raise spec.fail("", f"expected {_alternatives(spec.role)} ({spec.scheme}:// serves "
                            f"{what}, not the {spec.role} role)")
    protocols = _protocols(spec.scheme)
    if not protocols:
        return fits[0]
    default = _DEFAULTS.get((spec.scheme, spec.role))
    label = spec.path.strip("/")
    if spec.is_wire_sim and label in protocols and not spec.has("protocol"):
        default = label  # serial://sim/kiss: the simulated device names its protocol
    protocol = spec.text("protocol", default, choices=protocols)
    for e in fits:
        if e.protocol == protocol:
            return e
    verb = _VERB.get(spec.role, f"be the {spec.role} device")
    raise spec.fail("protocol", f"{protocol!r} cannot {verb}; use "
                                f"{' or '.join(str(e.protocol) for e in fits)}")


def backend(name: str, spec: DeviceUrl) -> Any:
    """``drivers.backends.<name>``, or a DeviceError saying which library is missing."""
    try:
        return importlib.import_module(f"drivers.backends.{name}")
    except ImportError as exc:
        missing = exc.name or (re.findall(r"No module named '([^']+)'", str(exc)) or [name])[0]
        lib = _PACKAGES.get(missing.split(".")[0], missing)
        raise DeviceError(f"{spec.where} url {spec.url!r}: the {spec.scheme}:// backend needs "
                          f"the Python package {lib} ({exc}); install it, e.g. "
                          f"`pip install {lib}`") from None

