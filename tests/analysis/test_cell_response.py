"""The step model through a cell's mechanics and its analytic Jacobian (a step fit's)."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.cell_response import CellDynamics, thrust_step, thrust_step_jacobian

T = np.linspace(-0.02, 0.2, 221)


@pytest.mark.parametrize("cell", [None, CellDynamics(150.0, 0.25), CellDynamics(150.0, 1.5)])
@pytest.mark.parametrize("square", [False, True])
@pytest.mark.parametrize("levels", [(2.3, 2.5), (2.5, 2.3), (-1.0, -1.5), (-0.5, 0.5)])
def test_jacobian_matches_finite_differences(cell, square, levels):
    p = np.array([0.012, 0.03, *levels])
    value, jac = thrust_step_jacobian(T, *p, cell, square)
    np.testing.assert_allclose(value, thrust_step(T, *p, cell, square), rtol=1e-12)
    # off the kink at the delayed step (a finite difference straddles it there)
    away = np.abs(T - p[0]) > 1e-4
    for i in range(4):
        h = np.zeros(4)
        h[i] = 1e-7 * max(abs(p[i]), 1e-2)
        num = (thrust_step(T, *(p + h), cell, square)
               - thrust_step(T, *(p - h), cell, square)) / (2.0 * h[i])
        scale = float(np.max(np.abs(num[away]))) or 1.0
        np.testing.assert_allclose(jac[away, i], num[away], atol=1e-5 * scale)
