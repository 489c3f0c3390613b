"""Run ids stay unique across benches and sort by start time."""

from __future__ import annotations

import re

from bench.run.recorder import new_run_id
from bench.run.run_ids import uuid7


def test_uuid7_layout_and_order() -> None:
    a, b = uuid7(1_700_000_000_000), uuid7(1_700_000_000_001)
    assert a.version == 7 and a.variant == "specified in RFC 4122"
    assert a.int >> 80 == 1_700_000_000_000 and a < b


def test_run_ids_of_one_microsecond_differ_and_keep_their_name() -> None:
    ids = {new_run_id("step1") for _ in range(5000)}
    assert len(ids) == 5000
    assert all(re.fullmatch(r"\d{8}T\d{6}_\d{6}Z-[0-9a-f]{8}-step1", i) for i in ids)
