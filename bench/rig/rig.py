"""Rig files: the one rig config of every bench (devices by role, the bench's own
sections), loaded and validated up front, and the static thrust map written back.

``load_rig(path)`` (propulsion stand), ``load_imu_rig(path)`` (IMU bench, ``[rig] kind =
"imu"``) and ``load_any_rig(path)`` (whichever the file is) return a frozen
:class:`RigConfig`; any problem raises ``bench.errors.RigError`` naming the file, the
field and what was expected. The devices are parsed by :mod:`bench.rig.rig_devices`, each
bench's own tables by its section module (:mod:`bench.rig.rig_propulsion`,
:mod:`bench.rig.rig_imu`), chosen by the file's ``[rig] kind`` through :data:`BENCH_SECTIONS`.

The static thrust map measured by a sweep (Paper C section 4.4) lives in a CSV side file
the rig file references (``[thrust_map] file = ...``); ``save_thrust_map`` writes it
atomically so the step sequences can turn thrust setpoints into ESC commands. Shipped
(or read-only) rigs are never rewritten: the map goes into a copy of the rig under the
run output folder (``map_goes_to_copy``, ``save_thrust_map(..., dest_dir=...)``).
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from analysis.atomic_files import write_atomically
from bench.errors import RigError
from bench.paths.inputs import check_input
from bench.paths.outputs import permits_writing
from bench.rig import rig_imu, rig_propulsion
from bench.rig.rig_devices import URL_SCHEMES, DeviceConfig
from bench.rig.rig_imu import HEXAPOD_LIMIT_MAXIMA, HexapodSettings, ImuSettings, ImuSimConfig
from bench.rig.rig_propulsion import (
    ESC_MODES,
    FRAME_RATE_RANGE_HZ,
    LIMIT_MAXIMA,
    PULSE_RANGE_US,
    ROLES,
    CalibrationSite,
    Components,
    EscConfig,
    Limits,
    SimConfig,
    ThrustMap,
    make_thrust_map,
)
from bench.rig.rig_table import RigTable, read_rig_toml
from bench.rig.shipped_rigs import shipped_rig

__all__ = ["BENCH_SECTIONS", "ESC_MODES", "FRAME_RATE_RANGE_HZ", "HEXAPOD_LIMIT_MAXIMA",
           "LIMIT_MAXIMA", "PULSE_RANGE_US", "ROLES", "URL_SCHEMES", "Components",
           "DeviceConfig", "EscConfig", "HexapodSettings", "ImuSettings", "ImuSimConfig",
           "Limits", "RigConfig", "SimConfig", "ThrustMap", "default_imu_rig_path",
           "default_rig_path", "is_imu_rig", "is_shipped_rig", "load_any_rig",
           "load_imu_rig", "load_rig", "map_goes_to_copy", "rig_copy_path",
           "save_thrust_map"]

#: Each bench's own rig-file sections, by ``[rig] kind`` (no kind: the propulsion stand).
BENCH_SECTIONS: Mapping[str, Callable[[Path, RigTable], dict[str, Any]]] = {
    "propulsion": rig_propulsion.parse,
    "imu": rig_imu.parse,
}


def default_rig_path() -> Path:
    """The simulated rig every command uses when no ``--rig`` is given."""
    return shipped_rig("sim.toml")


def default_imu_rig_path() -> Path:
    """The simulated IMU bench ``rotorbench calibrate`` uses when no ``--rig`` is given."""
    return shipped_rig("sim-imu.toml")


def is_shipped_rig(path: str | os.PathLike[str]) -> bool:
    """True for a rig file inside the package's own rigs folder (``bench/data/rigs``).

    Shipped rigs are read-only references: a sweep stores a copy of them (with its map)
    under the output folder instead of rewriting tracked or installed files.
    """
    return Path(path).resolve().is_relative_to(default_rig_path().parent.resolve())


def map_goes_to_copy(rig: RigConfig) -> bool:
    """True if a new thrust map may not be written beside ``rig``'s file.

    That is a shipped rig, or one whose folder (or file, or existing map file) is not
    writable; ``save_thrust_map(..., dest_dir=...)`` then stores a copy of the rig instead.
    """
    if is_shipped_rig(rig.path):
        return True
    target = rig.thrust_map_path or rig.path.with_name(f"{rig.path.stem}.thrust_map.csv")
    needed = [target.parent] + [p for p in (rig.path, target) if p.exists()]
    return not all(permits_writing(p) for p in needed)


def rig_copy_path(rig_path: str | os.PathLike[str], out: str | os.PathLike[str]) -> Path:
    """Where a sweep stores its copy of a read-only rig: ``<out>/rigs/<rig file name>``."""
    return Path(out) / "rigs" / Path(rig_path).name


# --- the one rig config ----------------------------------------------------------------------
@dataclass(frozen=True)
class RigConfig:
    """A validated rig file, whatever the bench: its devices by role, and the sections of
    its bench (None where another bench's): the propulsion stand's limits, components,
    ESC and thrust map; the IMU bench's hexapod, IMU and reference IMU. ``sim`` holds the
    bench's simulator settings (:class:`SimConfig` or :class:`ImuSimConfig`)."""

    path: Path
    name: str
    devices: Mapping[str, DeviceConfig]
    limits: Limits | None = None
    components: Components | None = None
    esc: EscConfig | None = None
    sim: Any = None
    thrust_map: ThrustMap | None = None
    thrust_map_path: Path | None = None  # side file named by [thrust_map] file
    description: str = ""
    hexapod: HexapodSettings | None = None
    imu: ImuSettings | None = None
    reference_imu: Mapping[str, float] | None = None
    calibration: CalibrationSite | None = None

    @property
    def kind(self) -> str:
        """``"imu"`` for an IMU bench (``[rig] kind = "imu"``), else ``"propulsion"``."""
        return "imu" if self.hexapod is not None else "propulsion"

    @property
    def is_simulated(self) -> bool:
        return all(d.scheme == "sim" for d in self.devices.values())

    def with_thrust_map(self, command_us: Sequence[float], thrust_n: Sequence[float]) -> RigConfig:
        tm = make_thrust_map(self.path, command_us, thrust_n, self.thrust_map_path)
        return replace(self, thrust_map=tm)

    def with_esc_mode(self, mode: str) -> RigConfig:
        """The same rig with another ESC scheme (``--esc-mode``): components and sim."""
        if mode not in ESC_MODES:
            modes = ", ".join(ESC_MODES)
            raise RigError(f"{self.path}: esc mode {mode!r}: expected one of {modes}")
        return replace(
            self,
            components=replace(self.components, esc_mode=mode),  # type: ignore[type-var]
            sim=replace(self.sim, esc_mode=mode),
        )

    def with_seed(self, seed: int) -> RigConfig:
        return replace(self, sim=replace(self.sim, seed=int(seed)))


# --- loading --------------------------------------------------------------------------------
def _kind_of(data: Mapping[str, Any]) -> str:
    head = data.get("rig")
    return "imu" if isinstance(head, dict) and head.get("kind") == "imu" else "propulsion"


def is_imu_rig(path: str | os.PathLike[str]) -> bool:
    """True when the file's ``[rig] kind`` is ``"imu"`` (unreadable files: False)."""
    try:
        data = read_rig_toml(Path(path))
    except RigError:
        return False
    return _kind_of(data) == "imu"


def _load(path: str | os.PathLike[str], kind: str | None) -> RigConfig:
    """The rig file read with the sections of bench ``kind`` (None: the file's own)."""
    path = check_input(path, "rig file").resolve()
    top = RigTable(path, "", read_rig_toml(path))
    parse = BENCH_SECTIONS[kind or _kind_of(top.data)]
    return RigConfig(**parse(path, top))


def load_rig(path: str | os.PathLike[str]) -> RigConfig:
    """Read and validate a propulsion rig file; raises ``RigError`` naming file and field."""
    path = check_input(path, "rig file").resolve()
    if _kind_of(read_rig_toml(path)) == "imu":
        raise RigError(f"{path}: [rig] kind = \"imu\": an IMU-bench rig (hexapod and IMUs); "
                       "this command needs a propulsion rig (esc, load_cell, power, rpm), e.g. "
                       "bench/data/rigs/sim.toml; the IMU bench runs with `rotorbench calibrate`")
    return _load(path, "propulsion")


def load_imu_rig(path: str | os.PathLike[str]) -> RigConfig:
    """Read and validate an IMU-bench rig file; raises ``RigError`` naming file and field."""
    return _load(path, "imu")


def load_any_rig(path: str | os.PathLike[str]) -> RigConfig:
    """Read and validate a rig file of either bench (by its ``[rig] kind``)."""
    return _load(path, None)


# --- writing the thrust map ---------------------------------------------------------------
def _atomic_write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomically(path, lambda tmp: tmp.write_text(text, encoding="utf-8", newline=""),
                     fsync=True)


def _copy_text(rig: RigConfig, map_name: str) -> str:
    """The rig file's text with ``[thrust_map] file`` naming ``map_name`` beside the copy.

    Everything else is copied verbatim: catalogs resolve against the package, not the
    rig file, so the thrust map is the only path that depends on where the file lies.
    """
    raw = rig.path.read_text(encoding="utf-8")
    data = read_rig_toml(rig.path)
    if "thrust_map" not in data:
        return raw.rstrip("\n") + f"\n\n[thrust_map]\nfile = {json.dumps(map_name)}\n"
    lines = raw.splitlines(keepends=True)
    header = re.compile(r"^\s*\[\s*thrust_map\s*\]\s*(#.*)?$")
    start = next((i for i, line in enumerate(lines) if header.match(line.rstrip("\r\n"))), None)
    if start is None:
        raise RigError(f"{rig.path}: [thrust_map]: expected a '[thrust_map]' header line")
    for i in range(start + 1, len(lines)):
        if lines[i].lstrip().startswith("["):
            break
        if re.match(r"^\s*file\s*=", lines[i]):
            lines[i] = f"file = {json.dumps(map_name)}\n"
            return "".join(lines)
    raise RigError(f"{rig.path}: [thrust_map] file: expected a 'file = ...' line")


def _write_map_csv(target: Path, command_us: Sequence[float],
                   thrust_n: Sequence[float]) -> ThrustMap:
    tm = make_thrust_map(target, command_us, thrust_n, target)
    lines = ["command_us,thrust_n"] + [f"{c:.6g},{f:.6g}" for c, f in
                                       zip(tm.command_us, tm.thrust_n, strict=True)]
    _atomic_write(target, "\n".join(lines) + "\n")
    return tm


def save_thrust_map(rig: RigConfig, command_us: Sequence[float], thrust_n: Sequence[float],
                    path: str | os.PathLike[str] | None = None,
                    dest_dir: str | os.PathLike[str] | None = None) -> RigConfig:
    """Write the measured thrust map as CSV next to the rig file, atomically.

    ``path`` defaults to the file the rig names in ``[thrust_map]``, else
    ``<rig stem>.thrust_map.csv``; if the rig file does not reference it yet, a
    ``[thrust_map]`` table is appended to the rig file (also atomically).
    With ``dest_dir`` the rig file is left alone: it is copied to ``dest_dir/<name>``
    (its ``[thrust_map] file`` pointing at the map beside the copy) and the map is
    written next to the copy (``path`` is then ignored).
    Returns the rig with the new map (for ``dest_dir``: the copy, loaded back).
    """
    if dest_dir is not None:
        copy = Path(dest_dir).resolve() / rig.path.name
        if copy == rig.path:
            raise RigError(f"{rig.path}: cannot copy the rig onto itself")
        source = rig.thrust_map_path or rig.path.with_name(f"{rig.path.stem}.thrust_map.csv")
        map_path = copy.with_name(source.name)
        text = _copy_text(rig, map_path.name)
        _write_map_csv(map_path, command_us, thrust_n)
        _atomic_write(copy, text)
        saved = load_rig(copy)
        if saved.thrust_map_path != map_path or saved.thrust_map is None:
            raise RigError(f"{copy}: [thrust_map] file does not name {map_path}")
        return replace(saved, components=rig.components, sim=rig.sim)
    target = Path(path).resolve() if path else (
        rig.thrust_map_path or rig.path.with_name(f"{rig.path.stem}.thrust_map.csv"))
    tm = _write_map_csv(target, command_us, thrust_n)
    if rig.thrust_map_path != target:
        raw = rig.path.read_text(encoding="utf-8")
        if "thrust_map" in read_rig_toml(rig.path):
            raise RigError(f"{rig.path}: [thrust_map] names {rig.thrust_map_path}; "
                           f"refusing to repoint it to {target}")
        rel = os.path.relpath(target, rig.path.parent)
        _atomic_write(rig.path, raw.rstrip("\n") + f'\n\n[thrust_map]\nfile = "{rel}"\n')
    return replace(rig, thrust_map=tm, thrust_map_path=target)
