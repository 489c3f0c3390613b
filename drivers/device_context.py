"""What the protocol entries share while one rig opens: ports, buses, tasks, peers, clock.

``drivers.factory.open_rig`` makes one :class:`DeviceContext` per opened rig and opens each
device with :meth:`DeviceContext.open`, a lookup in ``drivers.registry``. The entries
(``drivers.protocols``) keep what several roles share here, by key: a serial port (a board
printing thrust, speed and power serves three roles), a CAN bus, an NI-DAQmx task, the
simulated world behind the ``sim`` host's peers. ``close()`` closes it all in reverse
order (host side first, then the simulated peers and their plant).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import drivers.protocols  # noqa: F401  (the entries register themselves on import)
from drivers.contracts import Clock, Sensor
from drivers.device_options import DeviceUrl
from drivers.errors import DeviceError
from drivers.registry import lookup
from drivers.rig_view import RigView
from drivers.role_views import SharedSensor

__all__ = ["DEFAULT_COLUMNS", "DeviceContext"]

DEFAULT_COLUMNS = {"load_cell": ("thrust_n",), "power": ("current_a", "voltage_v"),
                   "rpm": ("rpm",)}


class DeviceContext:
    """The shared state of one rig's devices while they open and run.

    ``world``: builds (once, on first use) the simulated world the simulated devices and
    the ``sim`` host's peers read: a ``drivers.sim_worlds`` object of the rig's bench.
    """

    def __init__(self, rig: RigView, clock: Clock, specs: dict[str, DeviceUrl], *,
                 world: Callable[[], Any] | None = None, seed: int | None = None) -> None:
        self.rig = rig
        self.clock = clock
        self.specs = specs
        self.seed = seed
        self.open_timeout_s = 2.0  # how long a device may take to answer when opened
        self.one_world = False  # devices share one simulated world on its own clock
        self._make_world = world
        self._world: Any = None
        self.wire: Any = None  # the simulated peers' owner (drivers.wire_sim.plant_peers)
        self.peers: dict[str, Any] = {}  # role -> the simulated device behind it, if any
        self.answers: dict[str, str] = {}  # role -> what the device said when opened
        self.probes: dict[str, Callable[[float], str]] = {}  # role -> a sign of life
        self._closers: list[Callable[[], None]] = []
        self._shared: dict[tuple, Any] = {}
        self._shared_opts: dict[tuple, dict[str, Any]] = {}

    # -- opening ------------------------------------------------------------------------
    def open(self, spec: DeviceUrl) -> Any:
        """The device of ``spec``, opened by its registry entry; errors name the device."""
        try:
            dev = lookup(spec).open(self, spec)
            try:
                spec.check_used()
            except DeviceError:
                dev.close()  # opened before the typo was found: do not leak its threads
                raise
            return dev
        except DeviceError as exc:
            msg = str(exc)
            if msg.startswith(spec.rig_path):
                raise
            raise DeviceError(f"{spec.where} {spec.url!r}: {msg}") from None

    def world(self) -> Any:
        """The rig's simulated world (built on first use)."""
        if self._world is None:
            if self._make_world is None:
                raise DeviceError(f"{self.rig.path}: this rig has no simulated world")
            self._world = self._make_world()
        return self._world

    def set_world(self, builder: Callable[[], Any]) -> None:
        """How to build the simulated world when a device first needs it."""
        self._make_world = builder

    @property
    def built_world(self) -> Any:
        """The simulated world if a device has needed it, else None."""
        return self._world

    def probe(self, role: str, timeout_s: float) -> str:
        """What a device said: its identification, or a frame heard from it in time."""
        probe = self.probes.get(role)
        if probe is None:
            return self.answers.get(role, "opened")
        return probe(timeout_s)

    # -- sharing ------------------------------------------------------------------------
    def shared(self, key: tuple, make: Callable[[], Any],
               close: Callable[[Any], None] | None = None) -> Any:
        """One object per ``key`` (a port, a bus, a task) for every role that needs it."""
        if key not in self._shared:
            obj = make()
            self._shared[key] = obj
            if close is not None:
                self.on_close(lambda: close(obj))
        return self._shared[key]

    def has_shared(self, key: tuple) -> bool:
        return key in self._shared

    def shared_sensor(self, key: tuple, spec: DeviceUrl, make: Callable[[], Sensor]) -> Sensor:
        """This role's columns of one sensor device several roles may share (same options)."""
        opts = spec.device_options(exclude=("columns",))
        if ("sensor", *key) in self._shared:
            first = self._shared_opts[key]
            if opts != first:
                diff = sorted(k for k in set(opts) | set(first) if opts.get(k) != first.get(k))
                raise spec.fail(diff[0], "roles sharing one device must give it the same "
                                         f"options (differs from the first role: {diff})")
            for k in opts:
                spec.raw(k)
        self._shared_opts.setdefault(key, opts)
        shared: SharedSensor = self.shared(("sensor", *key), lambda: SharedSensor(make()))
        return shared.view(spec.role, spec.names("columns", DEFAULT_COLUMNS[spec.role]))

    # -- closing ------------------------------------------------------------------------
    def on_close(self, fn: Callable[[], None]) -> None:
        self._closers.append(fn)

    def close(self) -> None:
        errors = []
        while self._closers:
            fn = self._closers.pop()
            try:
                fn()
            except Exception as exc:  # close everything, report the first problem
                errors.append(exc)
        if errors:
            raise DeviceError(f"closing the rig's devices: {errors[0]}")
