"""Where the files the optimizer ships live: the datasheet catalogs (``thesis-e``,
``thesis-d``, the ``thesis-robot`` example) and the SizingLab open data.

They are package data under ``optimizer/data/``, found with :mod:`importlib.resources`, so
an installed ``rotorbench`` (a wheel, ``pip install .``) finds them as a clone does.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["CATALOGS", "SIZINGLAB", "shipped_path"]


def shipped_path(*parts: str) -> Path:
    """``optimizer/data/<parts>`` of the installed package, as a path.

    A wheel and a source tree both install the package as plain files, so the resource is
    a folder on disk (zip imports are not supported).
    """
    return Path(str(resources.files("optimizer").joinpath("data", *parts)))


#: the shipped catalog folders, one per catalog (``CATALOGS / "thesis-e"``)
CATALOGS = shipped_path("catalogs")
#: the Apache-2.0 SizingLab tables (see its SOURCE.md)
SIZINGLAB = shipped_path("sizinglab")
