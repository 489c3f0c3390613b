"""The closed loop of ``maneuvers.fly`` over a batch of designs, numpy over the designs.

The scalar modules are the reference (``CascadeController.update``, ``Mixer.mix``,
``RotorBank.step``, ``vehicle.step``, tested against solve_ivp and an independent
simulator) and stay plain floats, which is fastest for one design. This is their second
implementation on purpose, for many designs: each function here repeats their
floating-point operations in the same order on arrays of shape (B,) (one number per
design) or (N, B) (rotor x design), so a design flown here ends on the numbers ``fly``
ends on (tests/optimizer/flight/test_batch.py compares them).
Their branches become masks (``np.where``), Python's ``round`` is numpy's (both round half
to even) and sums over rotors are left folds like the scalar loops. Where a scalar step
adds a zero or multiplies by one, leaving it out changes at most the sign of a zero.

Per design the loop may differ in everything but the rotor count and layout: ESC frame
(sample and hold every ``frame_ticks``), latency (a ring of held commands read
``delay`` ticks back), time constants, gains. Non-finite numbers do not stop the loop
(floating-point warnings are silenced inside it): a diverged design stays non-finite
and its caller reports it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from optimizer.flight.batch_designs import DesignBatch
from optimizer.flight.controller import STOP_SHARE
from optimizer.flight.maneuvers import (
    GUST_FORCE_G,
    GUST_S,
    GUST_TORQUE_FRACTION,
    STEP_TIME_S,
    Maneuver,
    gust_tilt,
    step_quaternion,
)
from optimizer.flight.mixer import allocation_matrix, authority, mixing_matrix
from optimizer.flight.vehicle import pitch_angle, roll_angle, rotor_directions, yaw_angle

#: The angle a step of each attitude axis reads.
ANGLES = {"roll": roll_angle, "pitch": pitch_angle, "yaw": yaw_angle}


@dataclass
class Trace:
    """What the figures of a batch flight need, per tick (T) and design (B): the rest of
    the state is not kept."""

    t: np.ndarray  # (T,) s, the state after each tick
    saturated: np.ndarray  # (T, B) bool
    signal: np.ndarray  # (T, B) what the axis reads: angle, height, gust tilt; hover: none
    final: np.ndarray  # (13, B) the state at the end
    hover_speed_rad_s: np.ndarray  # (B,)
    omega_min: np.ndarray  # (B,) idle speed


def _fold(rows: np.ndarray) -> np.ndarray:
    """rows[0] + rows[1] + ... in that order (the scalar loops' sums over rotors)."""
    total = rows[0]
    for row in rows[1:]:
        total = total + row
    return total


def _combine(coefficients: tuple[float, ...], parts: tuple[np.ndarray, ...],
             zero: np.ndarray) -> np.ndarray:
    """c0 p0 + c1 p1 + ... left to right, as the scalar code writes a product with a
    constant quaternion, leaving out the terms of a zero coefficient and the product by
    a unit one (both exact but for the sign of a zero; a - c p = a + (-c) p exactly)."""
    total = None
    for c, part in zip(coefficients, parts, strict=True):
        if c == 0.0:
            continue
        term = part if c == 1.0 else -part if c == -1.0 else c * part
        total = term if total is None else total + term
    return zero if total is None else total


def _error_table(qd: tuple[float, ...]) -> tuple[tuple[float, ...], ...]:
    """Coefficients of q_e = q_d^-1 (x) q (B.2, B.3) on (qw, qx, qy, qz), one row per
    component of q_e, in the order of ``CascadeController.update``'s terms."""
    dw, dx, dy, dz = qd
    return ((dw, dx, dy, dz),  # on (qw, qx, qy, qz)
            (dw, -dx, -dy, dz),  # on (qx, qw, qz, qy)
            (dw, dx, -dy, -dz),  # on (qy, qz, qw, qx)
            (dw, -dx, dy, -dz))  # on (qz, qy, qx, qw)


class _Mixer:
    """``Mixer`` of every design: coefficients (N, B) and the saturation rule as masks."""

    def __init__(self, batch: DesignBatch, f_min: np.ndarray, f_max: np.ndarray) -> None:
        cos, sin, spin = rotor_directions(batch.n_rotors, batch.layout)
        arm = batch.arm_m[:, None]
        self.x, self.y = arm * cos, arm * sin  # (B, N), as Vehicle.rotor_positions
        self.spin = spin
        self.allocation = allocation_matrix(self.x, self.y, spin,
                                            (batch.k_m / batch.k_f)[:, None])
        matrix = mixing_matrix(self.allocation)  # (B, N, 4)
        self.roll, self.pitch, self.yaw = (np.ascontiguousarray(matrix[:, :, c].T)
                                           for c in range(3))
        self.share = matrix[:, 0, 3].copy()
        if not np.allclose(matrix[:, :, 3], self.share[:, None]):
            raise ValueError("mixer: the saturation rule needs equal thrust shares")
        self.lo, self.hi = f_min, f_max

    def mix(self, mx: np.ndarray, my: np.ndarray, mz: np.ndarray, thrust: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
        """``Mixer.mix`` for every design: thrusts (N, B) and the saturated flags (B,)."""
        lo, hi = self.lo, self.hi
        c = thrust * self.share
        f = mx * self.roll + my * self.pitch + c + mz * self.yaw
        inside = (lo <= np.minimum.reduce(f)) & (np.maximum.reduce(f) <= hi)
        if inside.all():  # the usual tick: nothing gives way
            return f, ~inside
        out = np.flatnonzero(~inside)  # the rule, on the designs that need it
        ruled, saturated = self._rule(out, mx[out], my[out], mz[out], c[out])
        f[:, out] = ruled
        flags = np.zeros(inside.size, bool)
        flags[out] = saturated
        return f, flags

    def _rule(self, cols: np.ndarray, mx: np.ndarray, my: np.ndarray, mz: np.ndarray,
              c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The saturation rule's three steps for designs ``cols``."""
        lo, hi = self.lo[cols], self.hi[cols]
        rp = mx * self.roll[:, cols] + my * self.pitch[:, cols]
        rp_lo, rp_hi = np.minimum.reduce(rp), np.maximum.reduce(rp)
        spread = rp_hi - rp_lo
        wide = spread > hi - lo  # step 1: scale roll/pitch together
        k = np.where(wide, (hi - lo) / spread, 1.0)
        rp, rp_lo, rp_hi = k * rp, k * rp_lo, k * rp_hi
        c_fit = np.minimum(hi - rp_hi, np.maximum(lo - rp_lo, c))  # step 2: thrust
        base = rp + c_fit
        yaw = self.yaw[:, cols]
        y = mz * yaw  # step 3: the largest yaw share that fits
        over = (y > 0.0) & (base + y > hi)
        under = (y < 0.0) & (base + y < lo)
        share = np.where(over, np.maximum(0.0, (hi - base) / y),
                         np.where(under, np.maximum(0.0, (lo - base) / y), 1.0))
        s = np.minimum(1.0, np.minimum.reduce(share))
        return base + (s * mz) * yaw, wide | (c_fit != c) | (s < 1.0)


class _Rotors:
    """``RotorBank`` of every design: speeds (N, B); frame and delay per design."""

    def __init__(self, batch: DesignBatch, dt: float, omega0: np.ndarray) -> None:
        n = batch.n_rotors
        self.omega_max = batch.omega_max_rad_s
        self.omega_min = batch.idle_fraction * batch.omega_max_rad_s
        # math.expm1 per design: the scalar bank's own function, not numpy's
        self.a_up = np.array([-math.expm1(-dt / t) for t in batch.tau_up_s])
        self.a_down = np.array([-math.expm1(-dt / t) for t in batch.tau_down_s])
        self.m_up = 1.0 - batch.tau_up_s * self.a_up / dt
        self.m_down = 1.0 - batch.tau_down_s * self.a_down / dt
        self.quantum = (self.omega_max - self.omega_min) / (batch.levels - 1)
        self.frame_ticks = np.maximum(1, np.rint(batch.frame_s / dt)).astype(int)
        self.delay = np.maximum(0, np.rint(batch.latency_s / dt)).astype(int)
        self.omega = np.broadcast_to(omega0, (n, omega0.size)).copy()
        self.held = self.omega.copy()
        # ring of held commands, slot k % size written at tick k; unwritten slots hold
        # the start speed, as the scalar bank's queue starts
        self.size = int(self.delay.max()) + 1
        self.ring = np.broadcast_to(self.held, (self.size, *self.held.shape)).copy()
        self.rows = np.arange(n)[:, None]
        self.cols = np.arange(omega0.size)[None, :]
        self.common_frame = int(self.frame_ticks[0]) \
            if np.all(self.frame_ticks == self.frame_ticks[0]) else 0
        self.common_delay = int(self.delay[0]) if np.all(self.delay == self.delay[0]) else -1
        self.tick = 0

    def step(self, command: np.ndarray) -> np.ndarray:
        """``RotorBank.step``: mean speeds (N, B) over the tick for commands (N, B)."""
        k = self.tick
        frame = None if self.common_frame else (k % self.frame_ticks == 0)
        if (self.common_frame and k % self.common_frame == 0) or \
                (frame is not None and frame.any()):
            lo, hi, q = self.omega_min, self.omega_max, self.quantum
            taken = lo + np.rint((np.minimum(hi, np.maximum(lo, command)) - lo) / q) * q
            self.held = taken if frame is None else np.where(frame, taken, self.held)
        self.tick += 1
        if self.common_delay == 0:
            target = self.held
        else:
            self.ring[k % self.size] = self.held
            if self.common_delay > 0:
                target = self.ring[(k - self.common_delay) % self.size]
            else:
                target = self.ring[((k - self.delay) % self.size)[None, :], self.rows,
                                   self.cols]
        w = self.omega
        d = target - w
        up = d > 0.0
        self.omega = w + d * np.where(up, self.a_up, self.a_down)
        return w + d * np.where(up, self.m_up, self.m_down)


def _authority(mixer: _Mixer, hover_f: np.ndarray) -> np.ndarray:
    """``mixer.authority`` of each design: (4, B) rows M_x, M_y, M_z, T."""
    return np.array([authority(a, lo, hi, h) for a, lo, hi, h in zip(
        mixer.allocation, mixer.lo.tolist(), mixer.hi.tolist(), hover_f.tolist(),
        strict=True)]).T


def _full_thrust(batch: DesignBatch) -> tuple[np.ndarray, np.ndarray]:
    """F_idle and F_max per design as ``fly`` computes them (Python's ``**``)."""
    f_min, f_max = [], []
    for k_f, w_max, idle_fraction in zip(batch.k_f.tolist(), batch.omega_max_rad_s.tolist(),
                                         batch.idle_fraction.tolist(), strict=True):
        idle = idle_fraction * w_max
        f_min.append(k_f * idle * idle)
        f_max.append(k_f * w_max ** 2)
    return np.array(f_min), np.array(f_max)


def simulate(batch: DesignBatch, man: Maneuver, dt: float) -> Trace:
    """Fly ``man`` with every design of ``batch`` (all valid): ``maneuvers.fly``'s tick,
    in its order, over arrays."""
    n = batch.n_rotors
    mass, g, cd = batch.mass_kg, batch.gravity_m_s2, batch.drag_n_s_m
    drag = bool(np.any(cd != 0.0))  # c_d v is left out when every c_d is 0
    ixx, iyy, izz = batch.ixx, batch.iyy, batch.izz
    k_f, k_m = batch.k_f, batch.k_m
    f_min, f_max = _full_thrust(batch)
    mixer = _Mixer(batch, f_min, f_max)
    w_hover = np.sqrt(mass * g / (n * k_f))  # Vehicle.hover_speed_rad_s
    rotors = _Rotors(batch, dt, 0.9 * w_hover if man.axis == "hover" else w_hover)
    hover_f = mass * g / n
    reach = _authority(mixer, hover_f)
    # CascadeController: 2 a of the square-root limits
    stop_x, stop_y, stop_z = (2.0 * STOP_SHARE * reach[r] / i
                              for r, i in enumerate((ixx, iyy, izz)))
    stop_v = 2.0 * STOP_SHARE * reach[3] / mass
    kp, wi, ka = batch.k_p, batch.w_i, batch.k_a
    ixx_kp, iyy_kp, izz_kp = ixx * kp, iyy * kp, izz * kp
    inv_m = 1.0 / mass
    inv_kf = 1.0 / k_f
    ys, xs = mixer.y.T.copy(), mixer.x.T.copy()  # (N, B)
    drag_torque = mixer.spin[:, None] * k_m  # spins[i] * k_m of the scalar loop
    d_iyz, d_izx, d_ixy = iyy - izz, izz - ixx, ixx - iyy

    steps = round(man.duration_s / dt)
    k_step = round(STEP_TIME_S / dt)
    tables = (_error_table((1.0, 0.0, 0.0, 0.0)), _error_table(step_quaternion(man)))
    z_step = man.amplitude if man.axis == "altitude" else 0.0
    gust_f = GUST_FORCE_G * mass * g
    gust_m = GUST_TORQUE_FRACTION * mass * g / n * batch.arm_m
    k_gust = round(GUST_S / dt)
    gusty = man.axis == "gust"

    b = mass.size
    zeros = np.zeros(b)
    # the state carried from tick to tick, (B,) each: declared, so that a type checker
    # reads them at these types in the tick below, rather than inferring them around the loop
    px: np.ndarray = zeros
    py: np.ndarray = zeros
    pz: np.ndarray = zeros
    vx: np.ndarray = zeros
    vy: np.ndarray = zeros
    vz: np.ndarray = zeros
    qw: np.ndarray = np.ones(b)
    qx: np.ndarray = zeros
    qy: np.ndarray = zeros
    qz: np.ndarray = zeros
    wx: np.ndarray = zeros
    wy: np.ndarray = zeros
    wz: np.ndarray = zeros
    i_x: np.ndarray = zeros
    i_y: np.ndarray = zeros
    i_z: np.ndarray = zeros
    i_climb: np.ndarray = zeros
    hold: np.ndarray = np.zeros(b, bool)
    sat = np.zeros((steps, b), bool)
    signal = np.empty((0 if man.axis == "hover" else steps, b))
    angle = ANGLES.get(man.axis)
    h = 0.5 * dt
    d6 = dt * dt / 6.0

    def tick(k: int) -> None:
        """One tick of every design: the loop body, a function so that a type checker reads
        the state at its declared types rather than inferring them around the loop."""
        nonlocal px, py, pz, vx, vy, vz, qw, qx, qy, qz, wx, wy, wz
        nonlocal i_x, i_y, i_z, i_climb, hold
        stepped = k >= k_step
        t_w, t_x, t_y, t_z = tables[stepped]
        z_d = z_step if stepped else 0.0
        # ---- CascadeController.update: q_e = q_d^-1 (x) q (B.2, B.3)
        ew = _combine(t_w, (qw, qx, qy, qz), zeros)
        ex = _combine(t_x, (qx, qw, qz, qy), zeros)
        ey = _combine(t_y, (qy, qz, qw, qx), zeros)
        ez = _combine(t_z, (qz, qy, qx, qw), zeros)
        sign = np.where(ew >= 0.0, -2.0, 2.0)  # 2 q_e1:3 ~ angle error (B.26)
        ax, ay, az = sign * ex, sign * ey, sign * ez
        # square-root limit per axis: min(max(w, -cap), cap) is copysign(cap, w)
        # where |w| > cap
        cap = np.sqrt(stop_x * np.abs(ax))
        sx = np.minimum(np.maximum(ka * ax, -cap), cap)
        cap = np.sqrt(stop_y * np.abs(ay))
        sy = np.minimum(np.maximum(ka * ay, -cap), cap)
        cap = np.sqrt(stop_z * np.abs(az))
        sz = np.minimum(np.maximum(ka * az, -cap), cap)
        er_x, er_y, er_z = sx - wx, sy - wy, sz - wz
        ez_m = z_d - pz  # altitude hold
        cap = np.sqrt(stop_v * np.abs(ez_m))
        climb = np.minimum(np.maximum(ka * ez_m, -cap), cap)
        ev = climb - vz
        if hold.any():  # conditional integration: hold while saturated
            i_x = np.where(hold, i_x, i_x + er_x * dt)
            i_y = np.where(hold, i_y, i_y + er_y * dt)
            i_z = np.where(hold, i_z, i_z + er_z * dt)
            i_climb = np.where(hold, i_climb, i_climb + ev * dt)
        else:
            i_x, i_y, i_z = i_x + er_x * dt, i_y + er_y * dt, i_z + er_z * dt
            i_climb = i_climb + ev * dt
        mx = ixx_kp * (er_x + wi * i_x)
        my = iyy_kp * (er_y + wi * i_y)
        mz = izz_kp * (er_z + wi * i_z)
        accel = kp * (ev + wi * i_climb)
        level_xy = qx * qx + qy * qy
        tilt = np.maximum(0.5, 1.0 - 2.0 * level_xy)
        thrust = mass * (g + accel) / tilt
        # ---- Mixer.mix, then the rotors' speed commands
        forces, hold = mixer.mix(mx, my, mz, thrust)
        sat[k] = hold
        w = rotors.step(np.where(forces > 0.0, np.sqrt(forces * inv_kf), 0.0))
        # (2.43)/(B.11): thrusts and drag torques of the rotor speeds
        w2 = w * w
        f = k_f * w2
        f_tot = _fold(f)
        m_x = _fold(ys * f)
        m_y = -_fold(xs * f)  # 0 - a - b = -(a + b): rounding is symmetric
        m_z = -_fold(drag_torque * w2)
        fy = None
        if gusty and k_step <= k < k_step + k_gust:
            shape = 0.5 * (1.0 - math.cos(2.0 * math.pi * (k - k_step) / k_gust))
            fy = gust_f * shape
            m_x = m_x + gust_m * shape
            m_y = m_y + gust_m * shape
        # ---- vehicle.step (fx = fz = 0; fy only in a gust)
        t2 = f_tot * 2.0
        acc_x = t2 * (qx * qz + qw * qy)
        acc_y = t2 * (qy * qz - qw * qx)
        acc_z = f_tot * (1.0 - 2.0 * level_xy)
        if fy is not None:
            acc_y = acc_y + fy
        if drag:
            acc_x, acc_y, acc_z = acc_x - cd * vx, acc_y - cd * vy, acc_z - cd * vz
        acc_x, acc_y, acc_z = acc_x * inv_m, acc_y * inv_m, acc_z * inv_m - g
        mxx = wx + h * (m_x + d_iyz * wy * wz) / ixx
        myy = wy + h * (m_y + d_izx * wz * wx) / iyy
        mzz = wz + h * (m_z + d_ixy * wx * wy) / izz
        nx = wx + dt * (m_x + d_iyz * myy * mzz) / ixx
        ny = wy + dt * (m_y + d_izx * mzz * mxx) / iyy
        nz = wz + dt * (m_z + d_ixy * mxx * myy) / izz
        ox, oy, oz = 0.5 * (wx + nx), 0.5 * (wy + ny), 0.5 * (wz + nz)
        rate = np.sqrt(ox * ox + oy * oy + oz * oz)
        half = 0.5 * rate * dt
        c = np.cos(half)
        kq = np.where(rate > 0.0, np.sin(half) / rate, 0.5 * dt)
        rx, ry, rz = kq * ox, kq * oy, kq * oz
        pw_ = qw * c - qx * rx - qy * ry - qz * rz
        px_ = qw * rx + qx * c + qy * rz - qz * ry
        py_ = qw * ry - qx * rz + qy * c + qz * rx
        pz_ = qw * rz + qx * ry - qy * rx + qz * c
        norm = 1.0 / np.sqrt(pw_ * pw_ + px_ * px_ + py_ * py_ + pz_ * pz_)
        pw_, px_, py_, pz_ = pw_ * norm, px_ * norm, py_ * norm, pz_ * norm
        # at the step's end: the new attitude, drag on the Euler-predicted velocity
        b_x = t2 * (px_ * pz_ + pw_ * py_)
        b_y = t2 * (py_ * pz_ - pw_ * px_)
        b_z = f_tot * (1.0 - 2.0 * (px_ * px_ + py_ * py_))
        if fy is not None:
            b_y = b_y + fy
        if drag:
            b_x = b_x - cd * (vx + dt * acc_x)
            b_y = b_y - cd * (vy + dt * acc_y)
            b_z = b_z - cd * (vz + dt * acc_z)
        b_x, b_y, b_z = b_x * inv_m, b_y * inv_m, b_z * inv_m - g
        px = px + dt * vx + d6 * (2.0 * acc_x + b_x)
        py = py + dt * vy + d6 * (2.0 * acc_y + b_y)
        pz = pz + dt * vz + d6 * (2.0 * acc_z + b_z)
        vx, vy, vz = vx + h * (acc_x + b_x), vy + h * (acc_y + b_y), vz + h * (acc_z + b_z)
        qw, qx, qy, qz = pw_, px_, py_, pz_
        wx, wy, wz = nx, ny, nz
        # ---- what the figures read
        if angle is not None:
            signal[k] = angle(qw, qx, qy, qz)
        elif man.axis == "altitude":
            signal[k] = pz
        elif gusty:
            signal[k] = gust_tilt(roll_angle(qw, qx, qy, qz), pitch_angle(qw, qx, qy, qz))

    with np.errstate(all="ignore"):
        for k in range(steps):
            tick(k)
    final = np.array([px, py, pz, vx, vy, vz, qw, qx, qy, qz, wx, wy, wz])
    return Trace(np.arange(steps) * dt + dt, sat, signal, final, w_hover, rotors.omega_min)
