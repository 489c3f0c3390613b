"""Fault switches on the simulated devices: dropout, spikes, stuck value, timeout, disconnect.

A device owns one ``FaultSwitches``; tests (or a rig file's ``options.faults``) turn faults
on for a window of simulated time. Sample faults transform the blocks a sensor hands out;
TIMEOUT and DISCONNECT make reads and commands raise ``DeviceError``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, TypeAlias, TypedDict

import numpy as np

from drivers.contracts import Block, Fault
from drivers.errors import DeviceError


@dataclass
class FaultSwitch:
    """One active fault: its window in sim time and parameters."""

    fault: Fault
    at_s: float = 0.0
    until_s: float = math.inf
    probability: float = 1.0  # DROPOUT: share of samples lost; SPIKES: share of samples hit
    fill_nan: bool = False  # DROPOUT: keep the rows but fill NaN instead of dropping them

    def active(self, t: float) -> bool:
        return self.at_s <= t < self.until_s


#: ``FaultSwitches.snapshot``: generator state, switches, stuck values, last values.
FaultsSnapshot: TypeAlias = tuple[
    Mapping[str, Any], list[FaultSwitch], dict[str, float] | None, dict[str, float]]


class FaultOptions(TypedDict, total=False):
    """The keywords of ``FaultSwitches.inject`` (and of the devices' ``inject``)."""

    at_s: float
    until_s: float
    probability: float | None
    fill_nan: bool


class FaultSwitches:
    """The set of faults switched on for one device."""

    def __init__(self, device: str, rng: np.random.Generator, allowed: tuple[Fault, ...]) -> None:
        self.device = device
        self.rng = rng
        self.allowed = allowed
        self.switches: list[FaultSwitch] = []
        self._stuck: dict[str, float] | None = None
        self._last: dict[str, float] = {}

    def inject(
        self,
        fault: Fault | str,
        *,
        at_s: float = 0.0,
        until_s: float = math.inf,
        probability: float | None = None,
        fill_nan: bool = False,
    ) -> None:
        fault = Fault(fault)
        if fault not in self.allowed:
            names = ", ".join(f.value for f in self.allowed)
            raise ValueError(f"{self.device}: fault {fault.value!r} not supported; use {names}")
        if probability is None:
            probability = 0.002 if fault is Fault.SPIKES else 1.0
        if not 0.0 <= probability <= 1.0:
            raise ValueError(f"{self.device}: fault probability {probability} not in [0, 1]")
        self.switches.append(FaultSwitch(fault, at_s, until_s, probability, fill_nan))

    def clear(self, fault: Fault | str | None = None) -> None:
        if fault is None:
            self.switches.clear()
        else:
            f = Fault(fault)
            self.switches = [s for s in self.switches if s.fault is not f]
        self._stuck = None

    def snapshot(self) -> FaultsSnapshot:
        stuck = None if self._stuck is None else dict(self._stuck)
        return self.rng.bit_generator.state, list(self.switches), stuck, dict(self._last)

    def restore(self, snap: FaultsSnapshot) -> None:
        """Back to a ``snapshot`` (a simulated rig's checkpoint)."""
        rng, switches, stuck, last = snap
        self.rng.bit_generator.state = rng
        self.switches = list(switches)
        self._stuck = None if stuck is None else dict(stuck)
        self._last = dict(last)

    def _find(self, fault: Fault, t: float) -> FaultSwitch | None:
        for s in self.switches:
            if s.fault is fault and s.active(t):
                return s
        return None

    def check(self, t: float, what: str) -> None:
        """Raise ``DeviceError`` if the device is disconnected or timing out at time ``t``."""
        if self._find(Fault.DISCONNECT, t):
            raise DeviceError(f"{self.device}: device disconnected ({what} failed at t={t:.4f} s)")
        if self._find(Fault.TIMEOUT, t):
            raise DeviceError(
                f"{self.device}: device timed out ({what} got no reply at t={t:.4f} s)")

    def blocked(self, t: float) -> bool:
        return bool(self._find(Fault.DISCONNECT, t) or self._find(Fault.TIMEOUT, t))

    def apply(self, block: Block, full_scale: dict[str, float]) -> Block:
        """Apply the sample faults (stuck, spikes, dropout) to a fresh block."""
        n = len(block)
        if n == 0 or not self.switches:
            if n:
                self._last = {k: float(v[-1]) for k, v in block.values.items()}
            return block
        t = block.t_s
        values = {k: v.copy() for k, v in block.values.items()}
        keep = np.ones(n, dtype=bool)
        if not any(s.fault is Fault.STUCK and s.at_s < t[-1] and s.until_s > t[0]
                   for s in self.switches):
            self._stuck = None
        for s in self.switches:
            mask = (t >= s.at_s) & (t < s.until_s)
            if not mask.any():
                continue
            if s.fault is Fault.STUCK:
                if self._stuck is None:  # freeze at the last value before the fault
                    first = int(np.argmax(mask))
                    if first > 0:
                        self._stuck = {k: float(v[first - 1]) for k, v in values.items()}
                    else:
                        self._stuck = self._last or {k: float(v[0]) for k, v in values.items()}
                for k, v in values.items():
                    v[mask] = self._stuck[k]
            elif s.fault is Fault.SPIKES:
                hit = mask & (self.rng.random(n) < s.probability)
                for k, v in values.items():
                    v[hit] = full_scale[k]
            elif s.fault in (Fault.TIMEOUT, Fault.DISCONNECT):
                keep &= ~mask  # nothing was acquired while the device was unreachable
            elif s.fault is Fault.DROPOUT:
                lost = mask & (self.rng.random(n) < s.probability)
                if s.fill_nan:
                    for v in values.values():
                        v[lost] = np.nan
                else:
                    keep &= ~lost
        self._last = {k: float(v[-1]) for k, v in values.items()}
        if not keep.all():
            return Block(t[keep], {k: v[keep] for k, v in values.items()})
        return Block(t, values)
