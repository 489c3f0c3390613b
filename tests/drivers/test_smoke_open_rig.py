"""The default rig opens, spins and reports plausible numbers (first-version smoke test)."""

from __future__ import annotations

import numpy as np

from bench.rig.rig import default_rig_path, load_rig
from drivers.factory import open_rig


def test_default_rig_spins_up_and_reports_lined_up_columns():
    rig = load_rig(default_rig_path())
    with open_rig(rig) as r:
        r.esc.arm()
        cell, power, rpm = (r.sensors[k] for k in ("load_cell", "power", "rpm"))
        for _ in range(60):
            r.esc.set_pulse_us(1650)
            r.clock.sleep(0.025)
            b_cell, b_pow, b_rpm = cell.read_block(), power.read_block(), rpm.read_block()
        np.testing.assert_array_equal(b_cell.t_s, b_pow.t_s)
        np.testing.assert_array_equal(b_cell.t_s, b_rpm.t_s)
        truth = r.truth()
        assert truth is not None and truth.armed
        assert abs(np.mean(b_rpm.values["rpm"]) - truth.rpm) < 0.02 * truth.rpm
        assert 1.0 < truth.thrust_n < 5.0
        assert abs(np.mean(b_pow.values["current_a"]) - truth.current_bus_a) < 0.1
    assert not r.sim.esc_model.armed or r.sim.esc_model.events  # disarm queued on close
