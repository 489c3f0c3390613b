"""What a sweep is, as JSON: kept in its Parquet file and checked before a resume.

Two runs may share finished chunks only when they fly the same designs with the same
numbers: the same catalog (by content, not only by path), options, maneuvers and code
version, and the same plan (its digest covers every key and flight parameter, so a
changed measured store or constant shows too). How the sweep runs (workers, scheduler,
chunk size) is not part of it: the rows do not depend on it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Mapping, Sequence
from typing import Any

import pandas as pd
from pandas.util import hash_pandas_object

from optimizer.catalogs.catalog import Catalog

#: the Parquet key-value metadata key that holds the spec (and marks a sweep file)
METADATA_KEY = "rotorbench_sweep"
#: the layout of the rows and parts; a resume across layouts is refused
FORMAT = 1


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("rotorbench")
    except PackageNotFoundError:  # a source tree without install
        return "unknown"


def frame_digest(frame: pd.DataFrame) -> str:
    """SHA-256 (16 hex digits) of a frame's columns and values, row order included."""
    h = hashlib.sha256(json.dumps(list(map(str, frame.columns))).encode())
    # pandas-stubs do not type pandas.util's functions
    hashed = hash_pandas_object(frame, index=False)  # pyright: ignore[reportCallIssue]
    h.update(hashed.to_numpy().tobytes())
    return h.hexdigest()[:16]


def catalog_digest(catalog: Catalog) -> str:
    """A digest of the catalog's parts and constants (its content, whatever its path)."""
    h = hashlib.sha256()
    for frame in (catalog.propellers, catalog.motors, catalog.batteries):
        h.update(frame_digest(frame.astype(str)).encode())
    h.update(json.dumps(dataclasses.asdict(catalog.constants), sort_keys=True,
                        default=str).encode())
    return h.hexdigest()[:16]


def sweep_spec(catalog: Catalog, plan: pd.DataFrame, maneuvers: Sequence[str],
               options: Mapping[str, Any], samples: int = 1, seed: int = 0
               ) -> dict[str, Any]:
    """The spec of a sweep: ``options`` are the command's (payload, actuators, hover
    margin, rules, measured store, packs, layout, drag, step run), as JSON values;
    ``samples`` flights per design (``--samples``) drawn with ``seed``."""
    return {
        "format": FORMAT,
        "version": _version(),
        "catalog": catalog.source,
        "catalog_digest": catalog_digest(catalog),
        "options": dict(options),
        "maneuvers": list(maneuvers),
        "samples": int(samples),
        "seed": int(seed),
        "designs": len(plan),
        "plan_digest": frame_digest(plan),
    }


def spec_difference(old: Mapping[str, Any], new: Mapping[str, Any],
                    prefix: str = "") -> str | None:
    """The first entry two specs differ in, as ``key: old there, new now`` (nested keys
    joined by dots: ``options.rules.tip_speed_m_s``); None if equal."""
    for key in dict.fromkeys([*old, *new]):
        a, b = old.get(key), new.get(key)
        if _canonical(a) == _canonical(b):
            continue
        if isinstance(a, Mapping) and isinstance(b, Mapping):
            inner = spec_difference(a, b, f"{prefix}{key}.")
            if inner is not None:
                return inner
        return (f"{prefix}{key}: {json.dumps(a, default=str)} there, "
                f"{json.dumps(b, default=str)} now")
    return None


def _canonical(value: Any) -> str:
    """JSON text of a value, so a tuple here equals the list read back from a file."""
    return json.dumps(value, sort_keys=True, default=str)
