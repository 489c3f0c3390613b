"""Device discovery goes through the backend link modules (the only vendor importers)."""

from __future__ import annotations

import drivers.discovery as disc
from drivers.backends import can_link, serial_link


def test_can_detection_reports_python_cans_configs_as_rig_urls():
    found, note = disc.can_configs(interfaces=("virtual",), timeout_s=5.0)
    assert note == ""
    assert found and all(c.interface == "virtual" and c.channel for c in found)
    assert found[0].url == f"can://virtual/{found[0].channel}"


def test_a_failing_can_interface_is_a_note_not_an_error(monkeypatch):
    def broken(interface: str) -> list[tuple[str, str]]:
        raise OSError("vendor library missing")

    monkeypatch.setattr(can_link, "detect_configs", broken)
    found, note = disc.can_configs(interfaces=("pcan", "kvaser"), timeout_s=5.0)
    assert found == []
    assert note == "pcan: vendor library missing; kvaser: vendor library missing"


def test_serial_listing_failure_is_a_note(monkeypatch):
    def broken() -> list[tuple[str, str, str]]:
        raise OSError("no sysfs")

    monkeypatch.setattr(serial_link, "list_ports", broken)
    assert disc.serial_ports() == ([], "listing serial ports failed: no sysfs")


def test_serial_ports_become_rig_urls(monkeypatch):
    monkeypatch.setattr(serial_link, "list_ports", lambda: [("/dev/ttyACM0", "FC", "USB")])
    ports, note = disc.serial_ports()
    assert note == "" and ports[0].url == "serial:///dev/ttyACM0"
