"""Run ids stay unique across benches and sort by start time."""

from __future__ import annotations

import re

import pytest

from bench.engine.recorder import new_run_id
from bench.engine.run_ids import uuid7


def test_uuid7_layout_and_order() -> None:
    a, b = uuid7(1_700_000_000_000), uuid7(1_700_000_000_001)
    assert a.version == 7 and a.variant == "specified in RFC 4122"
    assert a.int >> 80 == 1_700_000_000_000 and a < b


def test_run_ids_of_one_microsecond_differ_and_keep_their_name() -> None:
    ids = {new_run_id("step1") for _ in range(5000)}
    assert len(ids) == 5000
    assert all(re.fullmatch(r"\d{8}T\d{6}_\d{6}Z-[0-9a-f]{8}-step1", i) for i in ids)


def test_every_kind_of_real_run_id_is_one() -> None:
    from bench.engine.run_ids import is_run_id

    made = [new_run_id(name) for name in ("step1", "sweep", "calibration", "imu-static")]
    imported = ["good", "log_2024-05-01", "stand-a.csv", "run:1+2"]  # `import --out` names
    assert all(is_run_id(i) for i in made + imported)


@pytest.mark.parametrize("bad", [
    "", "../../x", "..", ".", ".hidden", "a/b", "/etc/passwd", "a\\b", "..\\..\\x", "a\x00b",
    "x" * 129, "a..b", "-rf", "a b", "a\nb", "é", None, 12, ["a"],
])
def test_what_is_not_a_run_id_is_refused_naming_where(bad: object) -> None:
    from bench.engine.run_ids import check_run_id, is_run_id
    from bench.errors import RigError

    assert not is_run_id(bad)
    with pytest.raises(RigError, match=r"^spool run\.json: .* is not a run id") as err:
        check_run_id(bad, "spool run.json")
    assert "\n" not in str(err.value) and "\x00" not in str(err.value)
    assert len(str(err.value)) < 300


@pytest.mark.parametrize("name", ["my sequence", "a/../../b", "x\\y", "n\x00", "é" * 10,
                                  "z" * 300, "..", ""])
def test_a_sequence_name_of_any_kind_gives_a_run_id(name: str) -> None:
    from bench.engine.run_ids import is_run_id

    assert is_run_id(new_run_id(name))
