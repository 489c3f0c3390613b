"""Properties of rig limits and thrust maps (hypothesis)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.errors import RigError
from bench.rig.rig import Limits, ThrustMap

value = st.one_of(st.none(), st.floats(0.0, 1e4, allow_nan=False))
limits = st.builds(Limits, thrust_n=value, current_a=value, rpm=value,
                   voltage_min_v=value, voltage_max_v=value, temperature_c=value)
MAXIMA = ("thrust_n", "current_a", "rpm", "voltage_max_v", "temperature_c")


@settings(max_examples=300, deadline=None)
@given(rig=limits, seq=limits)
def test_tightening_never_loosens(rig, seq):
    def looser(name):
        mine, theirs = getattr(rig, name), getattr(seq, name)
        if mine is None or theirs is None:
            return False
        return theirs > mine if name in MAXIMA else theirs < mine

    names = (*MAXIMA, "voltage_min_v")
    if any(looser(n) for n in names):
        with pytest.raises(RigError, match="may only tighten"):
            rig.tightened(seq)
        return
    out = rig.tightened(seq)
    for n in names:
        mine, theirs, got = getattr(rig, n), getattr(seq, n), getattr(out, n)
        assert got == (theirs if theirs is not None else mine)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(0.0, 10.0, allow_nan=False), min_size=3, max_size=30))
def test_thrust_map_inverts_within_its_range(increments):
    thrust = np.cumsum(np.asarray(increments) + 1e-3)
    cmd = np.linspace(1000.0, 2000.0, thrust.size)
    tm = ThrustMap(tuple(cmd), tuple(thrust))
    probe = np.linspace(thrust[0], thrust[-1], 17)
    np.testing.assert_allclose(tm.thrust_for(tm.command_for(probe)), probe, rtol=1e-9, atol=1e-9)
