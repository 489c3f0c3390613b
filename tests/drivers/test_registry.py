"""The protocol registry: opening a device is a lookup by scheme, protocol option and role."""

from __future__ import annotations

from pathlib import Path

import pytest

import drivers.device_context  # noqa: F401  (registers the entries)
from bench.rig.rig import is_imu_rig, load_imu_rig, load_rig
from drivers import registry
from drivers.device_options import parse_device
from drivers.errors import DeviceError

RIGS = Path(__file__).resolve().parents[2] / "bench" / "data" / "rigs"


class Dev:
    def __init__(self, url: str, options: dict | None = None) -> None:
        self.url, self.options = url, options or {}


def _entry(role: str, url: str, **options) -> registry.Entry:
    return registry.lookup(parse_device("rig.toml", role, Dev(url, options)))


def test_one_entry_per_scheme_protocol_and_role():
    keys = [(e.scheme, e.protocol, r) for e in registry.entries() for r in e.roles]
    assert len(keys) == len(set(keys))
    assert {"serial", "can", "nidaq", "tcp", "sim", "replay"} <= set(registry.schemes())


@pytest.mark.parametrize(("role", "url", "options", "opener"), [
    ("esc", "serial:///dev/ttyACM0", {}, "msp_esc"),  # the serial ESC default
    ("imu", "serial:///dev/ttyACM0", {}, "msp_imu"),  # same protocol, other role
    ("power", "serial:///dev/ttyUSB0", {}, "loadcell_board"),
    ("power", "serial://sim/kiss", {}, "kiss_telemetry"),  # the simulated device's name
    ("rpm", "serial:///dev/ttyUSB1", {"protocol": "kiss"}, "kiss_telemetry"),
    ("reference_imu", "serial://sim/gx3", {}, "gx3_reference"),
    ("esc", "can://socketcan/can0", {"protocol": "dronecan"}, "dronecan_esc"),
    ("rpm", "can://virtual/x", {"protocol": "vesc"}, "vesc_telemetry"),
    ("esc", "nidaq://Dev1/ctr1", {}, "ni_esc"),
    ("hexapod", "tcp://192.168.0.10:50000", {}, "pi_hexapod"),
    ("load_cell", "replay:///tmp/x.npz", {}, "replay"),
    ("imu", "sim://imu", {}, "simulated"),
])
def test_lookup_finds_the_entry(role, url, options, opener):
    assert _entry(role, url, **options).open.__name__ == opener


@pytest.mark.parametrize(("role", "url", "options", "match"), [
    ("esc", "ftp://x", {}, r"\[devices.esc\] url 'ftp://x': unknown device URL scheme 'ftp'"),
    ("esc", "serial:///dev/x", {"protocol": "kiss"},
     r"options.protocol: 'kiss' cannot drive an ESC; use msp or vesc"),
    ("load_cell", "serial:///dev/x", {"protocol": "kiss"},
     r"'kiss' cannot be the load_cell device; use loadcell"),
    ("rpm", "serial:///dev/x", {"protocol": "smoke"}, r"'smoke': expected one of msp, vesc"),
    # every alternative named, in whatever order the protocols registered
    ("esc", "tcp://host", {}, r"^(?=.*expected sim://esc or )(?=.*serial://<port> "
                              r"\(protocol msp or vesc\))(?=.*can://)(?=.*msp\+tcp://)"
                              r"(?=.*\(tcp:// serves the PI GCS hexapod)"),
    ("hexapod", "can://sim/bus", {}, r"expected sim://hexapod or tcp://<host>\[:port\]"),
])
def test_lookup_errors_name_the_field_and_the_alternatives(role, url, options, match):
    with pytest.raises(DeviceError, match=match):
        _entry(role, url, **options)


def test_every_fixture_rig_resolves_in_the_registry():
    for path in sorted(RIGS.glob("*.toml")):
        rig = load_imu_rig(path) if is_imu_rig(path) else load_rig(path)
        for role, dev in rig.devices.items():
            entry = registry.lookup(parse_device(path, role, dev))
            assert role in entry.roles, (path.name, role)


def test_a_missing_vendor_library_names_the_package(monkeypatch):
    import importlib

    real = importlib.import_module

    def no_serial(name, *a, **k):
        if name == "drivers.backends.kiss_telemetry":
            raise ModuleNotFoundError("No module named 'serial'", name="serial")
        return real(name, *a, **k)

    monkeypatch.setattr(importlib, "import_module", no_serial)
    spec = parse_device("rig.toml", "rpm", Dev("serial:///dev/x", {"protocol": "kiss"}))
    with pytest.raises(DeviceError, match=r"rig.toml: \[devices.rpm\] url 'serial:///dev/x': the "
                                          r"serial:// backend needs the Python package pyserial"):
        registry.backend("kiss_telemetry", spec)
