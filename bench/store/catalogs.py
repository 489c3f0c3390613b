"""Which component catalog a command means: a folder, a shipped name, or the default.

The sizing commands take ``--catalog DIR``; a bare name that is no folder here but a
catalog shipped in ``optimizer/data/catalogs`` (``thesis-e``, ``thesis-d``) means that one; no
``--catalog`` means ``$ROTORBENCH_CATALOG`` or ``thesis-e``. A missing default (an
install without the source tree) is a one-line ``CatalogError``, not a traceback. Kept
out of the commands because ``optimize``, ``evaluate``, ``pareto``, ``fly`` and the demo
all resolve catalogs the same way.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from optimizer.catalogs.shipped_data import CATALOGS
from optimizer.errors import CatalogError

__all__ = ["SHIPPED_CATALOGS", "default_catalog", "load", "shipped_catalog", "with_current_model",
           "with_min_thrust_to_weight"]

SHIPPED_CATALOGS = CATALOGS


def default_catalog() -> Path:
    """The shipped catalog thesis-e (or $ROTORBENCH_CATALOG)."""
    env = os.environ.get("ROTORBENCH_CATALOG")
    if env:
        return _shipped_name(Path(env))
    return SHIPPED_CATALOGS / "thesis-e"


def shipped_catalog(name: str) -> Any:
    """The shipped catalog ``name`` (e.g. ``thesis-e``), whatever the environment says."""
    from optimizer.catalogs.catalog import load_catalog

    return load_catalog(SHIPPED_CATALOGS / name)


def _shipped_name(path: Path) -> Path:
    """A bare name that is no folder here but a shipped catalog (``thesis-d``) means it."""
    if not path.exists() and len(path.parts) == 1 and (SHIPPED_CATALOGS / path.name).is_dir():
        return SHIPPED_CATALOGS / path.name
    return path


def load(path: Path | None, current_model: str | None = None) -> Any:
    """Load a catalog; a missing default catalog is a clear error, not a traceback.

    ``current_model`` (``--current-model``) replaces the catalog's ``current_model``
    constant for this run (``optimizer.catalogs.model_constants``); None keeps the catalog's.
    """
    catalog = _load(path)
    return with_current_model(catalog, current_model)


def with_current_model(catalog: Any, current_model: str | None) -> Any:
    """``catalog`` with its current definition replaced (None: unchanged)."""
    import dataclasses

    if current_model is None or current_model == catalog.constants.current_model:
        return catalog
    constants = catalog.constants.with_updates(current_model=current_model)
    return dataclasses.replace(catalog, constants=constants)


def with_min_thrust_to_weight(catalog: Any, ratio: float | None) -> Any:
    """``catalog`` whose designs must reach full-throttle thrust-to-weight ``ratio`` (None:
    unchanged). The catalog's own ``min_thrust_to_weight``, where higher, stays: a design
    must meet both. The limit is then a check of every grid built from the catalog, so the
    MILP, enumeration, Pareto fronts and the flight sweep all see it."""
    import dataclasses

    own = catalog.constants.min_thrust_to_weight
    if ratio is None or (own is not None and own >= ratio):
        return catalog
    constants = catalog.constants.with_updates(min_thrust_to_weight=float(ratio))
    return dataclasses.replace(catalog, constants=constants)


def _load(path: Path | None) -> Any:
    from optimizer.catalogs.catalog import load_catalog

    folder = _shipped_name(path) if path is not None else default_catalog()
    if path is None and not folder.is_dir():
        if os.environ.get("ROTORBENCH_CATALOG"):
            raise CatalogError(f"ROTORBENCH_CATALOG={os.environ['ROTORBENCH_CATALOG']}: not a "
                               "catalog folder or a shipped catalog name")
        raise CatalogError(
            f"{folder}: default catalog not found (installed without the source tree?); "
            "pass --catalog DIR or set ROTORBENCH_CATALOG"
        )
    return load_catalog(folder)
