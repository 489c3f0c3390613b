"""The order `make test` hands test files to its processes: longest first, files whole."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import pytest

from tests.conftest import _longest_files_first


@dataclass
class _Item:
    path: Path
    name: str
    marks: dict[str, pytest.MarkDecorator] = field(default_factory=dict)

    def get_closest_marker(self, name: str):
        mark = self.marks.get(name)
        return mark.mark if mark is not None else None


def test_files_announcing_more_wall_time_start_first_and_stay_whole() -> None:
    quick, slow, long_ = Path("a_quick.py"), Path("b_slow.py"), Path("c_long.py")
    items = [_Item(quick, "q1"), _Item(slow, "s1"), _Item(slow, "s2", {"slow": pytest.mark.slow}),
             _Item(quick, "q2"), _Item(long_, "l1", {"slow": pytest.mark.slow(wall_s=120)}),
             _Item(long_, "l2")]
    items.sort(key=lambda i: str(i.path))  # as collected: a file's tests together
    _longest_files_first(items)  # type: ignore[arg-type]
    # the 120 s file first, then the bare slow mark (10 s), then the unmarked file
    assert [i.name for i in items] == ["l1", "l2", "s1", "s2", "q1", "q2"]

