"""`rotorbench export` options: hover thrust, all-up weight and motor count are checked."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.bench.conftest import imported_run
from tests.conftest import run_bad


@pytest.mark.parametrize("value", ["-1", "0", "nan"])
def test_export_hover_thrust_must_be_positive(tmp_path: Path, capsys, value: str) -> None:
    """--hover-thrust -1 printed MOT_THST_HOVER,-0.0842 (with exit code 0)."""
    run = imported_run(tmp_path)
    capsys.readouterr()
    err = run_bad(capsys, "export", "ardupilot", str(run), f"--hover-thrust={value}")
    assert "--hover-thrust: expected a thrust per motor > 0 N" in err


@pytest.mark.parametrize("json_flag", [[], ["--json"]], ids=["lines", "json"])
@pytest.mark.parametrize(("auw", "motors", "says"), [
    ("nan", "4", "--auw-kg: expected an all-up weight > 0 kg, got nan"),
    ("inf", "4", "--auw-kg: expected an all-up weight > 0 kg, got inf"),
    ("-1", "4", "--auw-kg: expected an all-up weight > 0 kg, got -1"),
    ("1.2", "0", "--motors: expected a count >= 1, got 0"),
    ("1.2", "-4", "--motors: expected a count >= 1, got -4"),
])
def test_export_auw_and_motors_are_checked(tmp_path: Path, capsys, auw: str, motors: str,
                                           says: str, json_flag: list[str]) -> None:
    """`--auw-kg nan --motors 4` printed MOT_THST_HOVER,nan (exit 0) and, with
    --json, a ValueError traceback."""
    run = imported_run(tmp_path)
    capsys.readouterr()
    err = run_bad(capsys, "export", "ardupilot", str(run), f"--auw-kg={auw}",
                  f"--motors={motors}", *json_flag)
    assert says in err
