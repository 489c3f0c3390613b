"""The load cell's 2nd-order filter in numpy: the same output as scipy's ``lfilter`` on
the ``bilinear`` coefficients, bit for bit the same whatever the block slicing."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from drivers.sim.load_cell_filter import SecondOrderLowPass, bilinear_low_pass

FS = 25_000.0


def _reference(fn_hz: float, zeta: float, x: np.ndarray) -> np.ndarray:
    wn = 2.0 * math.pi * fn_hz
    b, a = signal.bilinear([wn * wn], [1.0, 2.0 * zeta * wn, wn * wn], fs=FS)
    return signal.lfilter(b, a, x)


def _input(n: int = 60_000) -> np.ndarray:
    rng = np.random.default_rng(1)
    return rng.normal(size=n) * 2.0 + np.linspace(0.0, 5.0, n)


@pytest.mark.parametrize(("fn_hz", "zeta", "rel"), [
    (150.0, 0.25, 1e-11),  # the shipped cell
    (40.0, 0.05, 1e-10),  # barely damped: the longest memory
    (3000.0, 0.7, 1e-11),
    (150.0, 2.5, 1e-11),  # overdamped: two real poles
    (150.0, 0.9999, 1e-10),  # nearly a double pole
    (150.0, 1.0, 1e-5),  # a double pole, moved apart by 1e-6
])
def test_matches_lfilter(fn_hz: float, zeta: float, rel: float) -> None:
    b, a = bilinear_low_pass(fn_hz, zeta, FS)
    wn = 2.0 * math.pi * fn_hz
    b_ref, a_ref = signal.bilinear([wn * wn], [1.0, 2.0 * zeta * wn, wn * wn], fs=FS)
    np.testing.assert_allclose(b, b_ref, rtol=1e-12)
    np.testing.assert_allclose(a, a_ref, rtol=1e-12, atol=1e-15)
    x = _input()
    ref = _reference(fn_hz, zeta, x)
    got = SecondOrderLowPass(b, a)(x)
    assert np.abs(got - ref).max() <= rel * np.abs(ref).max()


@pytest.mark.parametrize(("fn_hz", "zeta"), [(150.0, 0.25), (3000.0, 0.7), (150.0, 2.5)])
def test_any_block_slicing_gives_the_same_bits(fn_hz: float, zeta: float) -> None:
    x = _input()
    whole = SecondOrderLowPass(*bilinear_low_pass(fn_hz, zeta, FS))(x)
    rng = np.random.default_rng(7)
    for cuts in (np.arange(500, x.size, 500), np.sort(rng.integers(0, x.size, 60)),
                 np.arange(1, 40)):
        f = SecondOrderLowPass(*bilinear_low_pass(fn_hz, zeta, FS))
        sliced = np.concatenate([f(part) for part in np.split(x, cuts)])
        assert np.array_equal(sliced, whole)


def test_snapshot_and_restore_repeat_the_output() -> None:
    x = _input(20_000)
    f = SecondOrderLowPass(*bilinear_low_pass(150.0, 0.25, FS))
    f(x[:1234])
    snap = f.snapshot()
    first = f(x[1234:9000])
    f(x[9000:])  # runs on past the snapshot
    f.restore(snap)
    assert np.array_equal(f(x[1234:9000]), first)
