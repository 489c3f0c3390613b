"""Rig files: loading, validation errors that name file and field, limits, thrust map."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from bench.errors import RigError
from bench.rig.rig import Limits, default_rig_path, load_rig, save_thrust_map
from drivers.errors import DeviceError
from drivers.factory import open_rig

DEFAULT_TEXT = default_rig_path().read_text()


def write_rig(tmp_path: Path, text: str, name: str = "rig.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def edited(old: str, new: str) -> str:
    assert old in DEFAULT_TEXT, old
    return DEFAULT_TEXT.replace(old, new, 1)


def test_default_rig_loads_with_all_roles_and_components():
    rig = load_rig(default_rig_path())
    assert rig.name == "sim" and rig.path == default_rig_path()
    assert set(rig.devices) == {"esc", "load_cell", "power", "rpm"}
    assert rig.devices["power"].calibration["current_mv_per_a"] == 36.60
    assert rig.devices["power"].calibration["voltage_mv_per_v"] == 63.69
    assert rig.is_simulated
    assert rig.components.esc_mode == rig.sim.esc_mode == "complementary"
    assert 50 <= rig.esc.frame_rate_hz <= 490
    assert rig.thrust_map is not None and rig.thrust_map.path.name == "sim.thrust_map.csv"
    # the stored map was measured on the sim: hover of a 1 kg quad needs ~1.6 ms
    assert 1550 < rig.thrust_map.command_for(0.25 * 9.81) < 1700


BAD = [
    ("missing device", ('[devices.rpm]\nurl = "sim://rpm"\nchannel = "ctr0"\n'
                        'calibration = { magnets = 14 }\n', ""),
     r"\[devices\] rpm: missing device"),
    ("bad url scheme", ('url = "sim://power"', 'url = "gopher://power"'),
     r"\[devices.power\] url: 'gopher://power': unknown scheme 'gopher'"),
    ("sim role mismatch", ('url = "sim://power"', 'url = "sim://rpm"'),
     r"\[devices.power\] url: .* must be sim://power"),
    ("frame rate high", ("frame_rate_hz = 400", "frame_rate_hz = 600"),
     r"\[esc\] frame_rate_hz: 600.* outside 50-490 Hz"),
    ("frame rate low", ("frame_rate_hz = 400", "frame_rate_hz = 20"),
     r"\[esc\] frame_rate_hz: 20.* outside 50-490 Hz"),
    ("pulse below 1000", ("idle_us = 1000", "idle_us = 900"), r"\[esc\] idle_us: 900.* 1000-2000"),
    ("pulse above 2000", ("max_us = 2000", "max_us = 2100"), r"\[esc\] max_us: 2100.* 1000-2000"),
    ("unknown top key", ("[rig]\n", "colour = 'red'\n[rig]\n"), r": colour: unknown key"),
    ("unknown nested key", ("thrust_n = 7.0", "thrust_n = 7.0\nthrust_lbf = 2"),
     r"\[limits\] thrust_lbf: unknown key"),
    ("unknown device key", ('channel = "pwm0"', 'channel = "pwm0"\nbaud = 9600'),
     r"\[devices.esc\] baud: unknown key"),
    ("voltages crossed", ("voltage_min_v = 9.0", "voltage_min_v = 13.0"),
     r"\[limits\] voltage_min_v: 13.0 V must be below"),
    ("bad esc mode", ('esc_mode = "complementary"', 'esc_mode = "turbo"'),
     r"\[components\] esc_mode: 'turbo'"),
    ("unknown plant parameter", ("[sim.plant]", "[sim.plant]\nwarp = 9"),
     r"\[sim.plant\] warp: unknown key"),
    ("wrong type", ("thrust_n = 7.0", 'thrust_n = "seven"'),
     r"\[limits\] thrust_n: expected a number"),
    ("missing limit", ("current_a = 25.0", ""), r"\[limits\] current_a: missing"),
]


@pytest.mark.parametrize("what,change,message", BAD, ids=[b[0] for b in BAD])
def test_invalid_rig_files_name_file_and_field(tmp_path, what, change, message):
    path = write_rig(tmp_path, edited(*change))
    with pytest.raises(RigError) as err:
        load_rig(path)
    text = str(err.value)
    assert text.startswith(str(path))
    assert re.search(message, text), text
    assert err.value.exit_code == 2


def test_not_toml_and_missing_file(tmp_path):
    with pytest.raises(RigError, match="not valid TOML"):
        load_rig(write_rig(tmp_path, "[rig\nname="))
    with pytest.raises(RigError, match="rig file not found"):
        load_rig(tmp_path / "nope.toml")


def test_components_are_checked_against_a_shipped_catalog(tmp_path):
    text = edited('catalog = "thesis-c"', 'catalog = "thesis-e"')
    text = text.replace('motor = "dji-2212-920kv"', 'motor = "M3"')
    text = text.replace('propeller = "8x4.5"', 'propeller = "P1"').replace(
        'battery = "3s-lipo"', 'battery = "B1"')
    assert load_rig(write_rig(tmp_path, text)).components.motor == "M3"
    with pytest.raises(RigError, match=r"\[components\] motor: 'M9' is not an id in .*motors.csv"):
        load_rig(write_rig(tmp_path, text.replace('motor = "M3"', 'motor = "M9"')))


def test_limits_can_only_be_tightened():
    rig = load_rig(default_rig_path())
    tighter = rig.limits.tightened(Limits(thrust_n=4.0, voltage_min_v=10.0))
    assert tighter.thrust_n == 4.0 and tighter.voltage_min_v == 10.0
    assert tighter.current_a == rig.limits.current_a  # unset fields are kept
    with pytest.raises(RigError, match=r"sim.toml: \[limits\] thrust_n: a sequence may only"):
        rig.limits.tightened(Limits(thrust_n=9.0))
    with pytest.raises(RigError, match=r"voltage_min_v"):
        rig.limits.tightened(Limits(voltage_min_v=8.0))
    with pytest.raises(RigError, match=r"rpm"):
        tighter.tightened(Limits(rpm=1e9))


def test_thrust_map_is_saved_atomically_and_referenced(tmp_path):
    text = DEFAULT_TEXT[: DEFAULT_TEXT.index("[thrust_map]")]
    rig = load_rig(write_rig(tmp_path, text))
    assert rig.thrust_map is None and rig.thrust_map_path is None
    cmd = np.arange(1000, 2001, 100.0)
    thrust = (cmd - 1000) ** 2 * 5e-6
    saved = save_thrust_map(rig, cmd, thrust)
    assert saved.thrust_map_path == tmp_path / "rig.thrust_map.csv"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rig.thrust_map.csv", "rig.toml"]
    again = load_rig(rig.path)
    np.testing.assert_allclose(again.thrust_map.thrust_n, thrust)
    assert again.thrust_map.command_for(1.25) == pytest.approx(1500.0, abs=3)
    with pytest.raises(RigError, match="outside the measured range"):
        again.thrust_map.command_for(100.0)
    with pytest.raises(RigError, match="must increase"):
        save_thrust_map(again, cmd[::-1], thrust)
    assert load_rig(rig.path).thrust_map.command_us == again.thrust_map.command_us


def test_with_thrust_map_and_esc_mode_return_new_configs():
    rig = load_rig(default_rig_path())
    other = rig.with_thrust_map([1000, 2000], [0.0, 5.0]).with_esc_mode("diode")
    assert other.thrust_map.command_for(2.5) == pytest.approx(1500)
    assert other.sim.esc_mode == other.components.esc_mode == "diode"
    assert rig.sim.esc_mode == "complementary"
    with pytest.raises(RigError, match="esc mode 'warp'"):
        rig.with_esc_mode("warp")


@pytest.mark.parametrize("url", ["serial:///dev/ttyUSB0", "can://socketcan/can0",
                                 "nidaq://Dev1/ai0", "tcp://localhost:50000"])
def test_hardware_devices_do_not_mix_with_sim_devices(tmp_path, url):
    # sim:// runs on the fast simulated clock, hardware on the wall clock
    rig = load_rig(write_rig(tmp_path, edited('url = "sim://load_cell"', f'url = "{url}"')))
    assert not rig.is_simulated
    with pytest.raises(DeviceError, match=r"rig.toml: \[devices\.esc\] .* cannot be mixed"):
        open_rig(rig)


def test_thesis_e_rig_uses_catalog_ids_and_its_thrust_map_holds():
    rig = load_rig(default_rig_path().with_name("sim-thesis-e.toml"))
    assert (rig.components.catalog, rig.components.motor, rig.components.propeller,
            rig.components.battery) == ("thesis-e", "M3", "P4", "B3")
    with open_rig(rig) as r:
        truth = r.truth()
        assert truth.params.diameter_m == 0.3556 and truth.params.r_ohm == 0.123
        for thrust in (3.0, 6.0, 9.0):
            pulse = rig.thrust_map.command_for(thrust)
            assert truth.steady_thrust_n(pulse) == pytest.approx(thrust, rel=0.02)


def test_bad_thrust_map_file_names_file_and_row(tmp_path):
    path = write_rig(tmp_path, DEFAULT_TEXT)
    (tmp_path / "sim.thrust_map.csv").write_text("command_us,thrust_n\n1000,0\n1500,heavy\n")
    with pytest.raises(RigError, match=r"sim.thrust_map.csv: row 3: expected numbers"):
        load_rig(path)
    (tmp_path / "sim.thrust_map.csv").write_text("cmd,force\n1000,0\n")
    with pytest.raises(RigError, match=r"sim.thrust_map.csv: thrust map needs columns"):
        load_rig(path)
