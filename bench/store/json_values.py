"""JSON-safe values for the stores and the web view: NaN and infinity become null (JSON has
neither; PostgreSQL's jsonb and a browser's JSON.parse refuse them) and numpy scalars
become Python numbers. One home for the run records, the constants and the pages."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = ["finite_number", "json_safe"]


def json_safe(obj: Any) -> Any:
    """``obj`` with mappings' keys as strings, tuples as lists, non-finite floats as None
    and numpy scalars as Python numbers, recursively."""
    if isinstance(obj, Mapping):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [json_safe(v) for v in obj]
    if isinstance(obj, np.generic):  # a numpy scalar
        return json_safe(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def finite_number(value: Any) -> float | None:
    """``value`` as a finite float; None for a value that is none (missing, null, text,
    NaN, infinity): what a stored JSON value or a sample cell may hold."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None
