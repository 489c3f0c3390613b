"""The clock offset between two recordings of the same signals (analysis/log_alignment.py)."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.log_alignment import clock_offset


def test_the_offset_of_two_clocks_is_found_to_a_fraction_of_the_grid():
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 8.0, 1e-3)
    steps = np.repeat(rng.uniform(1100, 1900, (80, 2)), t.size // 80 + 1, axis=0)[:t.size]
    x = steps + rng.normal(0, 2, steps.shape)
    offset = 1234.5678  # clock A reads this much more than clock B at the same instant
    # B: irregular samples (a log's jitter and a hole), its own zero
    tb = np.sort(rng.uniform(0.5, 7.5, 6000))
    tb = tb[(tb < 3.0) | (tb > 3.05)]
    xb = np.column_stack([np.interp(tb, t, x[:, k]) for k in range(2)])
    got = clock_offset(t + offset, x, tb, xb)
    assert got.offset_s == pytest.approx(offset, abs=3e-4)
    assert got.r > 0.5
    other = clock_offset(t + offset, x, tb, rng.permutation(xb))
    assert other.r < 0.1
