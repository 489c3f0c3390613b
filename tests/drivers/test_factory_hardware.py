"""Opt-in checks on a real bench (``pytest --run-hardware``): nothing here spins a motor.

Point ``ROTORBENCH_HARDWARE_RIG`` at the bench's rig file (serial://, can://, nidaq://
devices); the test connects to every device and needs each to answer, like
``rotorbench check --rig FILE``.
"""

from __future__ import annotations

import os

import pytest

from bench.rig.rig import load_rig
from drivers.check import check_rig
from drivers.discovery import can_configs, serial_ports


def _rig_file() -> str:
    path = os.environ.get("ROTORBENCH_HARDWARE_RIG")
    if not path:
        pytest.skip("set ROTORBENCH_HARDWARE_RIG to the bench's rig file")
    return path


@pytest.mark.hardware
def test_every_device_of_the_bench_answers():
    reports = check_rig(load_rig(_rig_file()), timeout_s=3.0)
    failing = [f"{r.role} {r.url}: {r.detail}" for r in reports if not r.ok]
    assert not failing, failing


@pytest.mark.hardware
def test_the_bench_ports_are_visible():
    rig = load_rig(_rig_file())
    ports, _ = serial_ports()
    cans, _ = can_configs()
    urls = {p.url for p in ports} | {c.url for c in cans}
    for role, dev in rig.devices.items():
        base = dev.url.split("?")[0]
        if base.startswith(("serial://", "can://")) and "://sim" not in base:
            assert base in urls or base.startswith("can://virtual"), (role, base, sorted(urls))
