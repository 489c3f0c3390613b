"""Where the rig files the package ships live: the simulated rigs and their thrust maps.

They are package data under ``bench/data/rigs/``, found with :mod:`importlib.resources`,
so an installed ``rotorbench`` (a wheel, ``pip install .``) finds them as a clone does.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["SHIPPED_RIGS", "shipped_rig"]

#: the folder of the shipped rig files (a wheel installs it as plain files)
SHIPPED_RIGS = Path(str(resources.files("bench").joinpath("data", "rigs")))


def shipped_rig(name: str) -> Path:
    """The shipped rig file ``name`` (e.g. ``sim.toml``)."""
    return SHIPPED_RIGS / name
