"""Import an optional dependency, or say which rotorbench extra installs it."""

from __future__ import annotations

import importlib
from types import ModuleType

from analysis.errors import MissingExtraError

__all__ = ["import_extra"]


def import_extra(module: str, extra: str, purpose: str) -> ModuleType:
    """``importlib.import_module(module)``; if missing, a one-line error naming the extra.

    Optional packages stay optional: only the feature that needs one fails, and the
    message says how to get it (``pip install 'rotorbench[imu]'``).
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        top = module.split(".")[0]
        raise MissingExtraError(
            f"{purpose} needs the Python package {top} ({exc.__class__.__name__}: {exc}); "
            f"install the {extra} extra: pip install 'rotorbench[{extra}]'"
        ) from None
