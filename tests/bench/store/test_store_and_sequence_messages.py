"""Messages that blamed the wrong thing: a read-only constants store
was called unreadable ('move it away'), a sequence's unreachable thrust blamed the rig's
thrust-map file."""

from __future__ import annotations

import json
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from bench.errors import RigError
from bench.store.constants_store import ActuatorKey, ConstantsStore
from bench.store.run_index import RunIndex
from tests.conftest import run_bad

KEY = ActuatorKey("m1", "p1", "esc", "complementary", "3s")


def _lock(path: Path) -> bool:
    """Make ``path`` unwritable (mode bits, or immutable as root); False if impossible."""
    path.chmod(0o555 if path.is_dir() else 0o444)
    try:
        if path.is_dir():
            (path / ".probe").write_text("x")
            (path / ".probe").unlink()
        else:
            with path.open("r+b"):
                pass
    except OSError:
        return True
    return subprocess.run(["chattr", "+i", str(path)], capture_output=True).returncode == 0


@pytest.fixture
def locked() -> Iterator:
    paths: list[Path] = []

    def lock(path: Path) -> None:
        if not _lock(path):
            pytest.skip("cannot make a read-only file here (root without chattr)")
        paths.append(path)

    yield lock
    for p in paths:
        subprocess.run(["chattr", "-i", str(p)], capture_output=True)
        p.chmod(0o755 if p.is_dir() else 0o644)


def test_read_only_constants_store_says_read_only(tmp_path: Path, locked) -> None:
    store = ConstantsStore(tmp_path)
    store.put(KEY, "step", "run1", "runs/run1", {"tau_up_s": 0.03})
    locked(store.path)
    assert [r.run_id for r in store.rows()] == ["run1"]  # reading still works
    with pytest.raises(RigError) as info:
        store.put(KEY, "step", "run2", "runs/run2", {"tau_up_s": 0.04})
    msg = str(info.value)
    assert msg.startswith(f"{store.path}: cannot write the constants store (attempt to write "
                          "a readonly database)")
    assert "not a readable" not in msg and "move it away" not in msg


def test_store_in_a_read_only_folder_says_which_folder(tmp_path: Path, locked) -> None:
    folder = tmp_path / "ro"
    folder.mkdir()
    locked(folder)
    for make, what in ((lambda: ConstantsStore(folder).put(KEY, "step", "r", "r", {}),
                        "constants store"), (lambda: RunIndex(folder), "run index")):
        with pytest.raises(RigError) as info:
            make()
        name = "constants.sqlite" if what == "constants store" else "runs.sqlite"
        assert str(info.value).startswith(
            f"{folder / name}: cannot open the {what} (unable to open database file); check "
            f"that {folder} and {name} are writable")


def test_a_file_that_is_not_a_store_still_says_so(tmp_path: Path) -> None:
    (tmp_path / "constants.sqlite").write_bytes(b"\xac\x00 not a database" * 40)
    with pytest.raises(RigError, match=r"not a readable constants store .*move it away"):
        ConstantsStore(tmp_path).rows()


def test_unreachable_thrust_names_the_sequence_step(sim_rig_mapped_path: Path, tmp_path: Path,
                                                    capsys) -> None:
    seq = tmp_path / "high.json"
    seq.write_text(json.dumps({"name": "too-high", "steps": [
        # 6 N: above the map (5.2 N) but below the rig's thrust limit (7 N); a setpoint
        # at or above the limit is refused first (tests/bench/test_refused_before_run.py)
        {"kind": "arm"}, {"kind": "thrust_step", "thrust_n": 6.0, "hold_s": 1.0},
        {"kind": "disarm"}]}))
    for extra in ([], ["--dry-run"]):
        err = run_bad(capsys, "step", "--rig", str(sim_rig_mapped_path), "--sequence", str(seq),
                      "--out", str(tmp_path / "runs"), *extra)
        assert err.startswith(f"rotorbench: error: sequence 'too-high' ({seq}): steps[1]."
                              "thrust_n: 6 N is outside the rig's static thrust map (")
        assert "thrust_map.csv" not in err and "choose a setpoint inside it" in err
    assert not (tmp_path / "runs").exists()
