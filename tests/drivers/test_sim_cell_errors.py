"""The simulated load cell's hidden errors: what a calibration has to find."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.sim.cell_errors import CellErrors, CellErrorState, apply_cell_errors
from drivers.sim.rig import SimRig
from drivers.sim.sensor_params import SensorParams

FS = 25_000


def _hold(errors: CellErrors, loads: list[float], hold_s: float = 2.0, chunk: int = 3333
          ) -> list[float]:
    """The output at the end of each hold, fed in reads of ``chunk`` samples."""
    state, n, ends = CellErrorState(), 0, []
    out = np.zeros(1)
    for x in loads:
        xs = np.full(int(hold_s * FS), x)
        for k in range(0, xs.size, chunk):
            out = apply_cell_errors(errors, state, xs[k:k + chunk], n, 1.0 / FS)
            n += out.size
        ends.append(float(out[-1]))
    return ends


def test_the_branches_are_the_model_and_do_not_depend_on_read_slicing():
    e = CellErrors(scale=0.02, nonlinearity=0.002, hysteresis=0.003)
    loads = [0.0, 0.5, 1.0, 0.5, 0.0]
    got = _hold(e, loads)
    assert got == pytest.approx([0.0, e.steady(0.5, 1), e.steady(1.0, 1), e.steady(0.5, -1),
                                 e.steady(0.0, -1)], abs=1e-12)
    assert got[3] - got[1] == pytest.approx(0.003)  # unloading reads higher by hyst
    assert _hold(e, loads, chunk=977) == pytest.approx(got, abs=1e-12)


def test_creep_approaches_its_share_of_the_load_and_recovers():
    e = CellErrors(creep=0.002, creep_tau_s=2.0)
    up, down = _hold(e, [1.0, 0.0], hold_s=20.0)
    assert up == pytest.approx(1.0 + 0.002, abs=1e-6)  # ten time constants
    assert down == pytest.approx(0.0, abs=1e-6)
    assert e.steady(1.0, 1, held_s=2.0) == pytest.approx(1.0 + 0.002 * (1 - np.exp(-1)))


def test_errors_drawn_from_a_seed_are_hidden_in_the_rig_and_a_weight_reads_through_them():
    p = SensorParams.with_overrides({"load_cell_error_seed": 7, "noise": False})
    errors = p.load_cell_errors
    assert errors == CellErrors.drawn(7) and errors.any
    assert abs(errors.scale) <= 0.03 and 0 <= errors.hysteresis <= 0.003
    rig = SimRig(sensor_params=p)
    rig.clock.sleep(0.5)
    zero = rig.load_cell.read_block().values["thrust_n"][-1]  # the bridge's own offset
    rig.acquisition.apply_force(rig.clock.now_ns() * 1e-9, 0.5 * 9.80665)
    rig.clock.sleep(1.5)  # lowered over 0.5 s, then held
    block = rig.load_cell.read_block()
    x = 0.5 * 9.80665 / p.load_cell_range_n
    expected = p.load_cell_range_n * errors.steady(x, 1, held_s=1.0)
    # the cell's mechanics have settled; the ADC's step is 0.3 mV = 3 mN
    assert block.values["thrust_n"][-1] - zero == pytest.approx(expected, abs=5e-3)
    assert abs(expected - 0.5 * 9.80665) > 5e-3  # ...and that is not the weight's force
