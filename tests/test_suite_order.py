"""The order `make test` hands test files to its processes: longest first, files whole."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from tests.conftest import _in_device_lane, _longest_files_first


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



def test_the_files_that_run_the_firmware_go_as_one_unit_of_their_summed_wall_time() -> None:
    from tests.conftest import DEVICE_LANE, DeviceLane

    long_, sitl_a, sitl_b = Path("c_long.py"), Path("test_sitl_a.py"), Path("test_x_sitl.py")
    wire = Path("test_a_wire.py")
    items = [_Item(wire, "w1", {"slow": pytest.mark.slow(wall_s=20)}),
             _Item(long_, "l1", {"slow": pytest.mark.slow(wall_s=80)}),
             _Item(sitl_a, "a1", {"slow": pytest.mark.slow(wall_s=40)}),
             _Item(sitl_b, "b1", {"slow": pytest.mark.slow(wall_s=30)})]
    _longest_files_first(items)  # type: ignore[arg-type]
    # 90 s of device files before the 80 s file, the firmware's first
    assert [i.name for i in items] == ["a1", "b1", "w1", "l1"]
    lane = object.__new__(DeviceLane)  # the scope rule alone (no xdist session here)
    assert {lane._split_scope(f"tests/drivers/{n}::t") for n in (sitl_a, sitl_b)} \
        == {DEVICE_LANE}
    assert lane._split_scope("tests/bench/commands/test_calibrate_wire.py::t") == DEVICE_LANE
    assert lane._split_scope("tests/drivers/test_imu_wire_rig.py::t") == DEVICE_LANE
    assert lane._split_scope("tests/bench/commands/test_calibrate_tcp.py::t") == DEVICE_LANE
    assert lane._split_scope("tests/drivers/test_other.py::t") == "tests/drivers/test_other.py"


#: what starts a firmware or a wire-level device world in a test file
STARTS_DEVICES = re.compile(r"rotorbench_tests_sitl|SitlProcess|WorldProcess\(|"
                            r"imu_world_process|wire_plant\(|def test_\w+\([^)]*\bsitl\b")


def test_files_that_start_device_stand_ins_are_in_the_device_lane() -> None:
    """Outside the lane a firmware or a world runs at a device's priority beside the lane's
    (docs/architecture.md, "One device lane"): a file that starts one is named into it."""
    here = Path(__file__)
    outside = [p.relative_to(here.parent).as_posix()
               for p in sorted(here.parent.rglob("test_*.py")) if p != here and
               not _in_device_lane(p) and STARTS_DEVICES.search(p.read_text("utf-8"))]
    assert outside == []
