"""Mixer: (B.27) for any layout, and the saturation rule.

(B.11) maps rotor thrusts F to body moments; (B.27) appends the total thrust row to make
it invertible for N = 4. For rotor i at (x_i, y_i) with spin s_i (+1 counter-clockwise):

    [M_x]   [  y_i      ]
    [M_y] = [ -x_i      ] F          (4 x N allocation matrix A)
    [M_z]   [ -s_i T_q  ]
    [ T ]   [  1        ]

(a counter-clockwise rotor's drag torque turns the frame clockwise). For N = 4 the
mixer is A^-1 exactly as (B.27); for N = 6, 8 it is the Moore-Penrose inverse A^+, the
allocation with the least sum of squared thrusts. A A^+ = I for every layout.

Saturation rule (attitude before thrust, yaw last), applied when a rotor's thrust would
leave [F_min, F_max] (idle and full-throttle speeds):
1. roll/pitch: if the spread of the roll/pitch thrusts exceeds F_max - F_min they are
   scaled down together (direction of the torque kept);
2. collective thrust: moved (up or down) by the least amount that fits the roll/pitch
   thrusts inside the limits: thrust gives way to attitude;
3. yaw: scaled by the largest factor in [0, 1] that keeps every rotor inside.
A tick where any step changed the demand counts as saturated.
"""

from __future__ import annotations

import numpy as np


def allocation_matrix(x: np.ndarray, y: np.ndarray, spin: np.ndarray,
                      torque_ratio_m: float | np.ndarray) -> np.ndarray:
    """A (4 x N): rotor thrusts -> [M_x, M_y, M_z, T], (B.11) plus the thrust row of (B.27).
    Positions of shape (B, N) and torque ratios of shape (B, 1) give a stack (B, 4, N)."""
    return np.stack([y, -x, -spin * torque_ratio_m, np.ones_like(x)], axis=-2)


def mixing_matrix(allocation: np.ndarray) -> np.ndarray:
    """(B.27): A^-1 for N = 4, the Moore-Penrose inverse A^+ otherwise (also of a stack)."""
    if allocation.shape[-2] == allocation.shape[-1]:
        return np.linalg.inv(allocation)
    return np.linalg.pinv(allocation)


def authority(allocation: np.ndarray, f_min: float, f_max: float,
              f_hover: float) -> tuple[float, float, float, float]:
    """What each row of A (M_x, M_y, M_z, T) can change by from hover, both ways: every
    rotor moved by the smaller hover margin Delta = min(f_max - f_hover, f_hover - f_min)
    in the direction of its row of A, sum_i |A_ri| Delta (exact for the symmetric
    layouts here; for the thrust row, N Delta, up or down)."""
    delta = max(0.0, min(f_max - f_hover, f_hover - f_min))
    m_x, m_y, m_z, thrust = (float(np.abs(allocation[r]).sum() * delta) for r in range(4))
    return m_x, m_y, m_z, thrust


class Mixer:
    """[M_x, M_y, M_z, T] -> N rotor thrusts within [f_min, f_max] by the saturation rule."""

    def __init__(self, allocation: np.ndarray, f_min: float, f_max: float) -> None:
        self.allocation = allocation
        self.matrix = mixing_matrix(allocation)
        self.n = allocation.shape[1]
        cols = self.matrix.tolist()
        self.roll_pitch = [(r[0], r[1]) for r in cols]
        self.yaw = [r[2] for r in cols]
        self.coeffs = [(r[0], r[1], r[2]) for r in cols]
        share = self.matrix[:, 3]
        if not np.allclose(share, share[0]):
            raise ValueError("mixer: the saturation rule needs equal thrust shares")
        self.share = float(share[0])
        self.f_min = f_min
        self.f_max = f_max

    def mix(self, mx: float, my: float, mz: float, thrust: float) -> tuple[list[float], bool]:
        """Rotor thrusts and whether the saturation rule changed the demand."""
        lo, hi = self.f_min, self.f_max
        c = thrust * self.share
        f = [mx * a + my * b + c + mz * y for a, b, y in self.coeffs]
        if lo <= min(f) and max(f) <= hi:  # the usual case: nothing to give way
            return f, False
        rp = [mx * a + my * b for a, b in self.roll_pitch]
        rp_lo, rp_hi = min(rp), max(rp)
        saturated = False
        if rp_hi - rp_lo > hi - lo:  # step 1: scale roll/pitch together
            k = (hi - lo) / (rp_hi - rp_lo)
            rp = [k * v for v in rp]
            rp_lo, rp_hi = k * rp_lo, k * rp_hi
            saturated = True
        c_fit = min(hi - rp_hi, max(lo - rp_lo, c))  # step 2: thrust gives way
        if c_fit != c:
            saturated = True
        s = 1.0  # step 3: the largest yaw share that fits
        for v, a in zip(rp, self.yaw, strict=True):
            b, y = v + c_fit, mz * a
            if y > 0.0:
                if b + y > hi:
                    s = min(s, max(0.0, (hi - b) / y))
            elif y < 0.0 and b + y < lo:
                s = min(s, max(0.0, (lo - b) / y))
        if s < 1.0:
            saturated = True
        sy = s * mz
        return [v + c_fit + sy * a for v, a in zip(rp, self.yaw, strict=True)], saturated
