"""``--measured [DIR]`` of ``rotorbench optimize`` / ``evaluate``: the constants store as
the optimizer's measured overrides, and per-design ``sources``.

DIR is the root the ``constants`` command and the bench commands write to (default
``./runs``, where ``constants.sqlite`` sits beside ``runs.sqlite``); a ``rotorbench demo``
output folder works too (its store is in ``<out>/runs``).
"""

from __future__ import annotations

import argparse
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from optimizer.errors import RequestError

#: Same default root as ``rotorbench constants --out`` and the bench commands.
DEFAULT_ROOT = Path("runs")


def add_measured_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--measured",
        type=Path,
        nargs="?",
        const=DEFAULT_ROOT,
        default=None,
        metavar="DIR",
        help="use measured time constants and hover currents from DIR/constants.sqlite "
        "where a combination has them (default DIR: ./runs; a demo output folder works)",
    )
    p.add_argument(
        "--esc-mode",
        default=None,
        help="with --measured: which ESC mode's constants (default: the mode stored for "
        "the most combinations)",
    )


@dataclass
class MeasuredSet:
    """The overrides of one store for one catalog and ESC mode."""

    store: Path
    esc_mode: str
    overrides: list[Any]
    grids: dict[int, Any] = field(default_factory=dict)

    def build_grid(self, catalog: Any, n: int, payload_kg: float) -> Any:
        """``optimize(build_grid=...)``: the model grid with the overrides; kept for sources."""
        from optimizer.design_model import evaluate_grid

        grid = evaluate_grid(
            catalog, n, payload_kg, overrides=self.overrides, esc_mode=self.esc_mode
        )
        self.grids[n] = grid
        return grid

    def annotate(self, result: Any) -> None:
        """Add ``sources`` to every design of a selection result built by ``build_grid``."""
        from optimizer.design_model import design_sources

        for d in result.designs:
            grid = self.grids.get(d.actuators)
            d.extra["sources"] = (
                design_sources(grid, *d.index) if d.index is not None and grid is not None
                else None
            )

    def describe(self) -> dict[str, Any]:
        return {
            "store": str(self.store),
            "esc_mode": self.esc_mode,
            "actuators_measured": len([o for o in self.overrides if o.esc_mode == self.esc_mode]),
        }


def find_store(folder: Path) -> Path:
    """The folder holding constants.sqlite: ``folder`` itself or ``folder/runs``."""
    from bench.constants_store import STORE_NAME

    for root in (folder, folder / "runs"):
        if (root / STORE_NAME).is_file():
            return root
    raise RequestError(
        f"--measured {folder}: no {STORE_NAME} there or in {folder / 'runs'} "
        "(store constants with `rotorbench constants --add RUN` or run `rotorbench demo`)"
    )


def load_measured_set(folder: Path, catalog: Any, esc_mode: str | None) -> MeasuredSet:
    """Overrides for ``catalog`` (matched by its folder name) and one ESC mode."""
    from bench.commands.constants import load_measured

    root = find_store(folder)
    name = Path(str(catalog.source)).name
    overrides = load_measured(root, catalog=name)
    if not overrides:
        others = sorted({o.propeller_id + "/" + o.motor_id for o in load_measured(root)})
        raise RequestError(
            f"--measured {root}: no constants stored for catalog {name!r} "
            f"(stored actuators of other rigs/catalogs: {', '.join(others[:8]) or 'none'})"
        )
    modes = Counter(o.esc_mode for o in overrides)
    if esc_mode is None:
        ranked = modes.most_common()
        if len(ranked) > 1 and ranked[0][1] == ranked[1][1]:
            raise RequestError(
                f"--measured {root}: ESC modes {', '.join(sorted(modes))} are stored for "
                "equally many combinations; choose one with --esc-mode"
            )
        esc_mode = ranked[0][0]
    elif esc_mode not in modes:
        raise RequestError(
            f"--esc-mode {esc_mode}: not in {root} (stored: {', '.join(sorted(modes))})"
        )
    return MeasuredSet(root, str(esc_mode), overrides)


def is_measured(sources: dict[str, str] | None, key: str) -> bool:
    return bool(sources) and str(sources.get(key, "")).startswith("measured")
