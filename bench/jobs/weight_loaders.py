"""Who puts the weights on: an operator answering a prompt, or an automatic fixture.

The bench never guesses that a weight is on: each step waits for the operator's Enter (or
the console's button), or for the fixture to report the load placed.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

__all__ = ["FixtureLoader", "Loader", "OperatorLoader", "sim_fixture", "weight_prompt"]


class Loader(Protocol):
    def load(self, force: float, mass_kg: float, step: int, total: int) -> None:
        """Return once ``mass_kg`` (its ``force``, or torque on an arm) is on the cell."""
        ...


def weight_prompt(mass_kg: float, step: int, total: int, *, cell: str, where: str,
                  confirm: str) -> str:
    """What the operator is asked at one step (the terminal's and the console's words)."""
    what = (f"take every weight off the {cell} cell" if mass_kg == 0 else
            f"make the weight {where} {mass_kg * 1e3:g} g in total")
    return f"[{step}/{total}] {what}, then {confirm}"


class OperatorLoader:
    """Prompts a person (``ask`` returns when they confirm; it raises to abort)."""

    def __init__(self, ask: Callable[[str], Any], cell: str, arm_m: float | None) -> None:
        self.ask = ask
        self.where = "on the load cell" if arm_m is None else f"on the arm at {arm_m:g} m"
        self.cell = cell

    def load(self, force: float, mass_kg: float, step: int, total: int) -> None:
        self.ask(weight_prompt(mass_kg, step, total, cell=self.cell, where=self.where,
                               confirm="press Enter "))


class FixtureLoader:
    """An automatic fixture: ``place(force)`` puts the load on and returns when it is."""

    def __init__(self, place: Callable[[float], None]) -> None:
        self.place = place

    def load(self, force: float, mass_kg: float, step: int, total: int) -> None:
        self.place(force)


def sim_fixture(rig: Any, cell: str = "thrust") -> FixtureLoader | None:
    """The simulated stand's fixture (weights lowered onto its simulated thrust cell, or
    hung on its torque cell's arm, at the simulated time), or None: a real stand has no
    fixture the bench knows of."""
    sim = getattr(rig, "sim", None)
    acquisition = getattr(sim, "acquisition", None)
    if sim is None or acquisition is None:
        return None
    clock = sim.clock
    apply = acquisition.apply_torque if cell == "torque" else acquisition.apply_force

    def place(load: float) -> None:
        apply(clock.now_ns() * 1e-9, load)

    return FixtureLoader(place)
