"""Test helper: rig files built from sim.toml with other [devices.*] tables."""

from __future__ import annotations

import re
from pathlib import Path

from bench.rig.rig import default_rig_path

ROLES = ("esc", "load_cell", "power", "rpm")


def rig_text(devices: dict[str, str], base: Path | None = None) -> str:
    """sim.toml (or ``base``) with the named devices' tables replaced by TOML bodies."""
    text = (base or default_rig_path()).read_text()
    for role, body in devices.items():
        pattern = re.compile(rf"\[devices\.{role}\]\n(?:(?!\n\[).)*", re.S)
        assert pattern.search(text), role
        text = pattern.sub(lambda _m, r=role, b=body: f"[devices.{r}]\n{b.strip()}", text)
    return text.replace('file = "sim.thrust_map.csv"', 'file = "none.thrust_map.csv"')


def write(tmp_path: Path, devices: dict[str, str], base: Path | None = None) -> Path:
    path = tmp_path / "rig.toml"
    path.write_text(rig_text(devices, base))
    return path
