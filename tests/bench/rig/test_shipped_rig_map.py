"""Shipped (or read-only) rigs are references: a sweep stores a copy with its map under --out."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

import bench.rig.rig as rig_module
from bench.cli import main
from bench.rig.rig import (
    default_rig_path,
    is_shipped_rig,
    load_rig,
    map_goes_to_copy,
    rig_copy_path,
    save_thrust_map,
)

FAST = ["--duration", "3"]  # a 3 s ramp still spans 1100-1900 us and fits a map


def _hashes(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.iterdir()) if p.is_file()}


def _run_json(out: Path, kind: str) -> dict:
    (run_dir,) = out.glob(f"*-{kind}")
    return json.loads((run_dir / "run.json").read_text(encoding="utf-8"))


def test_shipped_rig_detection(tmp_path):
    shipped = default_rig_path()
    assert is_shipped_rig(shipped)
    assert is_shipped_rig(shipped.parent / ".." / "rigs" / shipped.name)  # resolved, not textual
    assert map_goes_to_copy(load_rig(shipped))
    own = tmp_path / "sim.toml"
    own.write_bytes(shipped.read_bytes())
    assert not is_shipped_rig(own) and not map_goes_to_copy(load_rig(own))
    assert rig_copy_path(shipped, tmp_path / "out") == tmp_path / "out" / "rigs" / "sim.toml"


def test_sweep_then_step_on_the_default_rig_leaves_fixtures_untouched(tmp_path, capsys):
    rigs_dir = default_rig_path().parent
    before = _hashes(rigs_dir)
    out = tmp_path / "runs"
    assert main(["sweep", "--out", str(out), *FAST]) == 0
    printed = capsys.readouterr().out
    copy = out / "rigs" / "sim.toml"
    assert f"the rig with the new map is {copy.resolve()}" in printed
    assert f"`--rig {copy.resolve()}` uses it" in printed
    assert _hashes(rigs_dir) == before
    # the copy is the shipped file verbatim (it already names sim.thrust_map.csv beside it)
    assert copy.read_bytes() == default_rig_path().read_bytes()
    copied = load_rig(copy)
    assert copied.thrust_map_path == (out / "rigs" / "sim.thrust_map.csv").resolve()
    (sweep_dir,) = out.glob("*-sweep")
    fitted = json.loads((sweep_dir / "static_map.json").read_text(encoding="utf-8"))
    np.testing.assert_allclose(copied.thrust_map.command_us, fitted["command_us"], rtol=1e-6)
    np.testing.assert_allclose(copied.thrust_map.thrust_n, fitted["thrust_n"], rtol=1e-5)
    shipped_map = load_rig(default_rig_path()).thrust_map
    assert copied.thrust_map.thrust_n != shipped_map.thrust_n  # the new map, not a copy

    assert main(["step", "--out", str(out), "--repeats", "1"]) == 0
    printed = capsys.readouterr().out
    assert f"rig file: {copy}" in printed
    meta = _run_json(out, "step1")
    assert meta["rig"]["path"] == str(copy.resolve())
    np.testing.assert_allclose(meta["thrust_map"]["thrust_n"], copied.thrust_map.thrust_n)
    assert _hashes(rigs_dir) == before


def test_sweep_on_an_own_rig_stores_the_map_next_to_it(sim_rig_path, tmp_path, capsys):
    out = tmp_path / "runs"
    assert main(["sweep", "--rig", str(sim_rig_path), "--out", str(out), *FAST]) == 0
    map_file = sim_rig_path.with_name("sim.thrust_map.csv")
    assert f"stored with the rig: {map_file}" in capsys.readouterr().out
    assert map_file.is_file() and not (out / "rigs").exists()
    assert load_rig(sim_rig_path).thrust_map_path == map_file


def test_step_on_a_read_only_rig_without_map_sweeps_into_a_copy(sim_rig_path, tmp_path,
                                                                 monkeypatch, capsys):
    """The no-map path of ``step`` follows the rule too; here the rig folder is read-only.

    Tests run as root, where chmod does not stop writes, so write access is faked.
    """
    rig_dir = sim_rig_path.parent
    real = rig_module.permits_writing
    monkeypatch.setattr(rig_module, "permits_writing",
                        lambda p: not Path(p).resolve().is_relative_to(rig_dir) and real(p))
    before = _hashes(rig_dir)
    out = tmp_path / "runs"
    code = main(["step", "--rig", str(sim_rig_path), "--out", str(out), "--repeats", "1",
                 "--sequence", "step2"])
    assert code == 0
    printed = capsys.readouterr()
    assert "measuring one with a sweep first" in printed.err
    assert "is not writable, left unchanged" in printed.out
    assert _hashes(rig_dir) == before
    copy = (out / "rigs" / "sim.toml").resolve()
    # the copy gained the [thrust_map] table the original lacks, naming the map beside it
    assert load_rig(copy).thrust_map_path == copy.with_name("sim.thrust_map.csv")
    assert _run_json(out, "step2")["rig"]["path"] == str(copy)


def test_copy_repoints_a_map_file_in_another_folder(tmp_path):
    text = default_rig_path().read_text(encoding="utf-8").replace(
        'file = "sim.thrust_map.csv"', "file = 'maps/old.csv'  # measured in May")
    src = tmp_path / "ro" / "bench.toml"
    src.parent.mkdir()
    src.write_text(text, encoding="utf-8")
    rig = load_rig(src)
    cmd = np.arange(1100.0, 1901.0, 100.0)
    saved = save_thrust_map(rig, cmd, (cmd - 1000.0) ** 2 * 4e-6, dest_dir=tmp_path / "out")
    assert saved.path == tmp_path / "out" / "bench.toml"
    assert saved.thrust_map_path == tmp_path / "out" / "old.csv"
    np.testing.assert_allclose(saved.thrust_map.command_us, cmd)
    assert src.read_text(encoding="utf-8") == text and not (src.parent / "maps").exists()
    copied = saved.path.read_text(encoding="utf-8")
    assert copied == text.replace("file = 'maps/old.csv'  # measured in May", 'file = "old.csv"')
