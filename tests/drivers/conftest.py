"""Fixtures for the driver tests: rig configs, the step-fit and codec-check helpers, a CAN
bus with simulated nodes in processes of their own."""

from __future__ import annotations

import itertools
import sys
from collections.abc import Callable, Iterator
from dataclasses import replace
from typing import Any

import pytest
from rotorbench_tests_sitl import attach_logs, sitl  # noqa: F401  (tests/conftest.py loads it)

from bench.rig.rig import RigConfig, default_rig_path, load_rig


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> object:
    """A failed test that ran a SITL gets the firmware's log in its report."""
    outcome = yield
    attach_logs(item, outcome.get_result())  # type: ignore[attr-defined]


@pytest.fixture
def stepfit():
    """FOPDT fit and Paper C Step 1 runner (tests only)."""
    return sys.modules["rotorbench_tests_drivers_stepfit"]


@pytest.fixture
def default_rig() -> RigConfig:
    return load_rig(default_rig_path())


@pytest.fixture
def quiet_rig(default_rig: RigConfig) -> RigConfig:
    """The default rig without random noise or timestamp jitter."""
    return replace(default_rig, sim=replace(default_rig.sim, noise=False))


_can_channels = itertools.count()


class CanBench:
    """A host's python-can ``virtual`` bus (``host``, a CanLink) with simulated CAN nodes,
    each in a process of its own on a cable to the bus (``node``); closed backend first,
    then the nodes, then the bus."""

    def __init__(self) -> None:
        import can

        from drivers.backends.can_link import CanLink

        channel = f"can-bench-{next(_can_channels)}"
        self._buses = [can.Bus(interface="virtual", channel=channel) for _ in range(2)]
        self.host = CanLink(self._buses[0], "host")
        self._nodes_end = CanLink(self._buses[1], "nodes")
        self._closers: list[Callable[[], None]] = []

    def node(self, make: Callable[..., Any], settings: dict[str, Any], name: str) -> Any:
        """``make(port=..., **settings)`` in its process (``can_socket.node_process``);
        the node there, a ``Remote`` (``node.get("command")``)."""
        from drivers.wire_sim.can_socket import node_process

        remote, stop = node_process(self._nodes_end, make, settings, name)
        self._closers.append(stop)
        return remote

    def on_close(self, *close: Callable[[], None]) -> None:
        """Backends to close first (last given, first closed)."""
        self._closers.extend(close)

    def close(self) -> None:
        for close in reversed(self._closers):
            close()
        self.host.close()
        self._nodes_end.close()
        for bus in self._buses:
            bus.shutdown()


@pytest.fixture
def can_bench() -> Iterator[CanBench]:
    pytest.importorskip("can")
    bench = CanBench()
    yield bench
    bench.close()
