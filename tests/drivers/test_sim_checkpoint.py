"""The simulated rig's samples do not depend on how reads slice them, and a checkpoint
takes the whole rig back (what the runner's batches of ticks rely on)."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.sim.rig import SimRig


def _pulse(i: int) -> float:
    """A command pattern with steps, a ramp and a spin-down to rest and back."""
    phase = (i // 40) % 4
    if phase == 0:
        return 1450.0
    if phase == 1:
        return 1300.0 + 5.0 * (i % 40)
    if phase == 2:
        return 1000.0  # idle: the rotor coasts towards rest
    return 1600.0


def _drive(rig: SimRig, ticks: range, read_every: int, tick_s: float = 0.02) -> dict:
    blocks: dict[str, list] = {k: [] for k in rig.sensors}
    for i in ticks:
        rig.esc.set_pulse_us(_pulse(i))
        rig.clock.sleep(tick_s)
        if (i + 1) % read_every == 0 or i == ticks[-1]:
            for k, s in rig.sensors.items():
                blocks[k].append(s.read_block())
    return {k: (np.concatenate([b.t_s for b in v]),
                {c: np.concatenate([b.values[c] for b in v]) for c in v[0].values})
            for k, v in blocks.items()}


def _same(a: dict, b: dict) -> None:
    for role in a:
        assert np.array_equal(a[role][0], b[role][0]), role
        for name in a[role][1]:
            assert np.array_equal(a[role][1][name], b[role][1][name], equal_nan=True), name


@pytest.mark.parametrize("esc_mode", ["complementary", "diode", "stock"])
def test_samples_do_not_depend_on_the_read_slicing(esc_mode: str) -> None:
    rigs = [SimRig(seed=3, esc_mode=esc_mode) for _ in range(3)]
    runs = []
    for rig, every in zip(rigs, (1, 7, 50), strict=True):
        rig.esc.arm()
        runs.append(_drive(rig, range(400), every))
    assert runs[0]["rpm"][1]["rpm"].max() > 1000.0  # the rotor turned
    assert (runs[0]["rpm"][1]["rpm"] == 0.0).any()  # and came to rest in between
    _same(runs[0], runs[1])
    _same(runs[0], runs[2])


def test_a_checkpoint_takes_the_whole_rig_back() -> None:
    rig = SimRig(seed=5)
    rig.esc.arm()
    _drive(rig, range(100), 1)
    checkpoint = rig.checkpoint()
    t0 = rig.clock.now_ns()
    first = _drive(rig, range(100, 160), 60)
    truth = rig.truth()
    _drive(rig, range(160, 200), 10)  # more commands and reads, then back
    rig.restore(checkpoint)
    assert rig.clock.now_ns() == t0
    again = _drive(rig, range(100, 160), 60)
    _same(first, again)
    assert rig.truth() == truth


def test_runs_alone_only_without_faults_and_foreign_devices() -> None:
    rig = SimRig()
    devices = [rig.esc, *rig.sensors.values()]
    assert rig.runs_alone(rig.clock, devices)
    assert not rig.runs_alone(object(), devices)
    assert not rig.runs_alone(rig.clock, [*devices, object()])
    rig.power.inject("spikes", at_s=10.0)
    assert not rig.runs_alone(rig.clock, devices)


def test_a_checkpoint_taken_while_the_next_noise_is_drawn_ahead() -> None:
    """A long read has the next read's noise drawn in a thread; a checkpoint taken
    meanwhile does not wait for it, and going back gives the same samples again (and the
    same as reads of one tick each, which draw nothing ahead)."""
    rig = SimRig(seed=7)
    rig.esc.arm()
    _drive(rig, range(60), 60)  # one read of 1.2 s: the next read's rows are being drawn
    assert rig.acquisition._drawing.pending
    checkpoint = rig.checkpoint()
    first = _drive(rig, range(60, 120), 60)
    rig.restore(checkpoint)
    again = _drive(rig, range(60, 120), 60)
    _same(first, again)
    ref = SimRig(seed=7)
    ref.esc.arm()
    _drive(ref, range(60), 1)
    _same(first, _drive(ref, range(60, 120), 1))
