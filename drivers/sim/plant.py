"""The simulated actuator plant: supply -> ESC duty -> motor -> propeller (thesis E.1-E.7, C.1-C.4).

One seeded plant per simulated rig. The ESC model (``drivers.sim.esc``) hands the plant one
duty cycle per PWM frame; the plant integrates the rotor speed (and, optionally, the winding
current with inductance, C.1) over the frame in a few fixed substeps, and stores the
trajectory at the substep points. While the duty holds, the frames are one closed-form run
continued from call to call (numpy for long runs), so the plant can integrate lazily, when
the trajectory is looked at, with the same numbers wherever it is split. Sensors then sample
that trajectory at 25 kHz with vectorised interpolation, so no Python loop ever runs per
sample.

Every default parameter carries its source; ``docs/sim-rig.md`` lists them in a table.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, fields, replace

import numpy as np

from drivers.errors import DeviceError
from drivers.sim.trajectory import Trajectory


class EscScheme(enum.Enum):
    """Switching scheme of the ESC firmware (Paper C sections 2 and 3.3)."""

    COMPLEMENTARY = "complementary"  # active freewheeling: winding current may reverse (brakes)
    DIODE = "diode"  # body-diode freewheeling: current cannot reverse, coasts on drag
    STOCK = "stock"  # diode + the standard firmware's longer latency and input filter

    @classmethod
    def parse(cls, text: str) -> EscScheme:
        try:
            return cls(str(text).lower())
        except ValueError:
            names = ", ".join(m.value for m in cls)
            raise ValueError(f"unknown ESC mode {text!r}; expected one of {names}") from None


@dataclass(frozen=True)
class PlantParams:
    """Physical parameters of the simulated actuator, SI units. Defaults: DJI 2212/920 kV,
    8x4.5 in propeller, Hobbyking F30A ESC, 3S supply (Table C.2 unless noted)."""

    r_ohm: float = 0.22  # winding resistance R_a, Table C.2 (measured 0.220 V at 1.000 A)
    l_h: float = 80e-6  # winding inductance L_a, Table C.2 (Amprobe 37XR-A)
    use_inductance: bool = False  # C.2: L_a neglected (tau_e = L/R = 0.36 ms << tau_m)
    kt_nm_a: float = 0.0104  # torque constant K_T, Table C.2 (K_T = K_E, Hughes and Drury)
    ke_v_s_rad: float = 0.0104  # back-emf constant K_E from K_V = 920 RPM/V, Table C.2
    j_kg_m2: float = 17.2e-6  # inertia of motor + propeller J, Table C.2
    diameter_m: float = 0.2032  # 8 inch propeller, Paper C section 2.1
    ct: float = 0.1215  # thrust coefficient, APC 8x4.5MR static data at 6000 RPM (E.1)
    cp: float = 0.0518  # power coefficient, APC 8x4.5MR static data at 6000 RPM (E.2)
    rho_kg_m3: float = 1.225  # ISA sea-level air density
    friction_nm: float = 5e-4  # bearing (Coulomb) friction; E.7 omits it (assumption)
    supply_v: float = 11.1  # 3S LiPo nominal voltage (Table E.6: 11.1 V)
    supply_r_ohm: float = 0.025  # pack + wiring internal resistance (assumption; C.15: fast)
    esc_quiescent_a: float = 0.05  # ESC logic current draw (assumption)
    esc_latency_s: float = 0.012  # input-to-duty latency, SimonK firmware (set from Table C.1)
    stock_latency_s: float = 0.017  # input-to-duty latency, stock firmware (from Table C.1)
    esc_pwm_hz: float = 18_000.0  # motor PWM of the SimonK firmware (Paper C section 2.1)
    stock_pwm_hz: float = 18_000.0  # motor PWM of the stock firmware (assumption: same)
    diode_drop_v: float = 0.7  # MOSFET body-diode forward drop (assumption)
    stock_filter_tau_s: float = 0.020  # stock firmware throttle low-pass (from Table C.1 tau_up)
    max_substep_s: float = 0.0025  # integration substep (RK4), <= 1/10 of tau_m
    max_substep_l_s: float = 0.0005  # substep with inductance (exponential update of current)

    @classmethod
    def with_overrides(cls, overrides: dict[str, float]) -> PlantParams:
        """Defaults with the named fields replaced; unknown names raise ``KeyError``."""
        known = {f.name for f in fields(cls)}
        for name in overrides:
            if name not in known:
                raise KeyError(name)
        return replace(cls(), **overrides)

    # --- derived constants -------------------------------------------------------------
    @property
    def thrust_k(self) -> float:
        """F = k_f * omega^2, from F = C_t rho n^2 D^4 with n = omega / 2 pi (E.1)."""
        return self.ct * self.rho_kg_m3 * self.diameter_m**4 / (4.0 * math.pi**2)

    @property
    def torque_k(self) -> float:
        """T = k_q * omega^2, from W = C_p rho n^3 D^5 and T = W / omega (E.2, E.3)."""
        return self.cp * self.rho_kg_m3 * self.diameter_m**5 / (8.0 * math.pi**3)

    def latency_for(self, scheme: EscScheme) -> float:
        return self.stock_latency_s if scheme is EscScheme.STOCK else self.esc_latency_s

    def pwm_period_for(self, scheme: EscScheme) -> float:
        return 1.0 / (self.stock_pwm_hz if scheme is EscScheme.STOCK else self.esc_pwm_hz)

    def filter_tau_for(self, scheme: EscScheme) -> float:
        return self.stock_filter_tau_s if scheme is EscScheme.STOCK else 0.0


def thrust_n(params: PlantParams, omega_rad_s: np.ndarray | float) -> np.ndarray | float:
    """Propeller thrust (E.1)."""
    return params.thrust_k * np.square(omega_rad_s)  # (E.1)


def prop_torque_nm(params: PlantParams, omega_rad_s: np.ndarray | float) -> np.ndarray | float:
    """Propeller drag torque T = W / omega (E.2, E.3)."""
    return params.torque_k * np.square(omega_rad_s)  # (E.2), (E.3)


@dataclass(frozen=True)
class OperatingPoint:
    """The plant linearised at a steady thrust: speed, duty and time constants (C.3, E.8)."""

    thrust_n: float
    omega_rad_s: float
    duty: float
    current_bus_a: float
    tau_drive_s: float  # J / (K_T K_E / R + dT/domega): C.3 with D from the propeller, E.8
    tau_coast_s: float  # J / (dT/domega): no winding current (diode scheme decelerating)


def steady_omega(params: PlantParams, duty: float) -> float:
    """Rotor speed where motor torque equals propeller torque at a given duty (E.4-E.7)."""
    if duty <= 0.0:
        return 0.0
    r_tot = params.r_ohm + duty * duty * params.supply_r_ohm
    a = params.torque_k
    b = params.kt_nm_a * params.ke_v_s_rad / r_tot
    c = params.friction_nm - params.kt_nm_a * duty * params.supply_v / r_tot
    if c >= 0.0:
        return 0.0  # the motor cannot overcome friction
    return (-b + math.sqrt(b * b - 4.0 * a * c)) / (2.0 * a)


def operating_point(params: PlantParams, thrust: float) -> OperatingPoint:
    """Linearise the plant around the steady state that produces ``thrust`` newtons."""
    omega = math.sqrt(thrust / params.thrust_k)
    i_w = (params.torque_k * omega**2 + params.friction_nm) / params.kt_nm_a  # (E.6), (E.7)
    duty = 0.5
    for _ in range(20):  # the supply sag term depends on duty; a few fixed-point steps
        r_tot = params.r_ohm + duty * duty * params.supply_r_ohm
        duty = (params.ke_v_s_rad * omega + r_tot * i_w) / params.supply_v  # (E.4), (E.5)
    r_tot = params.r_ohm + duty * duty * params.supply_r_ohm
    drag_slope = 2.0 * params.torque_k * omega
    tau_drive = params.j_kg_m2 / (params.kt_nm_a * params.ke_v_s_rad / r_tot + drag_slope)
    tau_coast = params.j_kg_m2 / drag_slope
    return OperatingPoint(
        thrust_n=thrust,
        omega_rad_s=omega,
        duty=duty,
        current_bus_a=duty * i_w + params.esc_quiescent_a,
        tau_drive_s=tau_drive,
        tau_coast_s=tau_coast,
    )


class Plant:
    """Rotor speed (and optionally winding current) driven frame by frame by an ESC model.

    ``esc`` must provide ``frame_ns`` and ``latch(k) -> float``: the duty cycle the ESC
    applies during frame ``k`` (negative = transistors off, the motor coasts). A frame latched
    at ``k * frame`` acts on the motor from ``k * frame + latency`` on (input latency).
    """

    def __init__(self, params: PlantParams, esc: EscFrameSource, scheme: EscScheme) -> None:
        self.params = params
        self.scheme = scheme
        self.esc = esc
        self.latency_ns = round(params.latency_for(scheme) * 1e9)
        self.frame_ns = esc.frame_ns
        step = params.max_substep_l_s if params.use_inductance else params.max_substep_s
        self.n_sub = max(1, math.ceil(self.frame_ns * 1e-9 / step - 1e-9))
        self.k = 0  # next frame to integrate
        self.omega = 0.0
        self.theta = 0.0
        self.i_w = 0.0
        self.i_bus = params.esc_quiescent_a
        self.v_bus = params.supply_v - params.supply_r_ohm * self.i_bus
        self.duty = 0.0
        self._kq = params.torque_k
        # the closed-form run in progress (see ``_continue_run``), None after a stepped frame
        self._run: tuple[float, ...] | None = None
        self._due_ns = 0  # where the clock is: the plant integrates up to it when looked at
        self._traj = Trajectory()
        self._append(self.latency_ns * 1e-9)

    # The clock may run ahead of the plant by this much before a sleep integrates; the
    # result is the same wherever the integration is split, this only bounds the memory.
    MAX_LAG_NS = 2_000_000_000
    # Closed-form runs this short (substeps) are stepped in Python floats rather than numpy
    # arrays: the same operations in the same order, so the same numbers, only cheaper.
    SCALAR_RUN = 16

    _STATE = ("k", "omega", "theta", "i_w", "i_bus", "v_bus", "duty", "_run", "_due_ns")

    def snapshot(self) -> tuple[object, ...]:
        return (*(getattr(self, name) for name in self._STATE), self._traj.snapshot())

    def restore(self, snap: tuple[object, ...]) -> None:
        """Back to a ``snapshot`` (a simulated rig's checkpoint)."""
        for name, value in zip(self._STATE, snap[:-1], strict=True):
            setattr(self, name, value)
        self._traj.restore(snap[-1])  # type: ignore[arg-type]

    # ------------------------------------------------------------------------------------
    def _append(self, t: float) -> None:
        self._traj.pending.append(
            (t, self.omega, self.theta, self.i_w, self.i_bus, self.v_bus, self.duty))

    @property
    def traj(self) -> Trajectory:
        """The state history, integrated up to where the clock is (see ``due``)."""
        if self._due_ns > self.t_ns:
            self.advance_to(self._due_ns)
        return self._traj

    @property
    def t_ns(self) -> int:
        """Time up to which the plant state is known."""
        return self.k * self.frame_ns + self.latency_ns

    def due(self, t_ns: int) -> None:
        """The clock reached ``t_ns`` (its listener). The integration waits until someone
        looks (``traj``, ``advance_to``): a simulated run sends commands every tick but
        reads once per batch, and one integration per read costs far less than one per
        tick. It gives the same numbers wherever it is split (see ``_continue_run``)."""
        self._due_ns = t_ns
        if t_ns - self.t_ns > self.MAX_LAG_NS:  # commands pile up in the ESC meanwhile
            self.advance_to(t_ns)

    def advance_to(self, t_ns: int) -> None:
        """Integrate frame by frame until the state is known at ``t_ns`` (or later)."""
        if not math.isfinite(self.omega):
            raise DeviceError("sim plant diverged (non-finite rotor speed)")
        while self.t_ns < t_ns:
            duty = self.esc.latch(self.k)
            remaining = -(-(t_ns - self.t_ns) // self.frame_ns)
            span = self.esc.steady_frames(self.k, remaining) if remaining > 1 else 1
            n = self._continue_run(duty, span)
            if n == 0:
                self._integrate_frame(duty)
                self._run = None
                n = 1
            self.k += n

    def _new_run(self, duty: float) -> tuple[float, ...] | None:
        """The constants of the closed-form solution at a latched duty from the current
        state, or None where it does not apply (inductance, rotor at rest)."""
        p = self.params
        w0 = self.omega
        if p.use_inductance or w0 <= 0.0:
            return None
        coast = duty <= 0.0
        d = 0.0 if coast else duty
        kt, ke, j = p.kt_nm_a, p.ke_v_s_rad, p.j_kg_m2
        r_tot = p.r_ohm + d * d * p.supply_r_ohm
        if coast:
            a, b = -p.friction_nm / j, 0.0
        else:
            a = (kt * d * p.supply_v / r_tot - p.friction_nm) / j
            b = kt * ke / (r_tot * j)
        c = self._kq / j
        h = self.frame_ns * 1e-9 / self.n_sub
        disc = b * b + 4.0 * a * c
        if disc > 0.0:  # w = (w1 - u w2) / (1 - u), u shrinking by exp(-s h) per substep
            s = math.sqrt(disc)
            w1, w2 = (-b + s) / (2.0 * c), (-b - s) / (2.0 * c)
            return (duty, 0.0, w1, w2, math.exp(-s * h), (w0 - w1) / (w0 - w2))
        # no real equilibrium: the rotor decelerates on a tangent curve, w = g tan(arg) - shift
        shift, g = b / (2.0 * c), math.sqrt(-disc) / (2.0 * c)
        return (duty, 1.0, shift, g, c * g * h, math.atan((w0 + shift) / g))

    def _continue_run(self, duty: float, n_frames: int) -> int:
        """Up to ``n_frames`` frames at one duty in closed form (the Riccati solution of
        ``_integrate_frame``); returns how many it integrated (0: the caller steps one).

        A run of frames at one duty continues one sequence, ``u_k = u_(k-1) q`` or
        ``arg_k = arg_(k-1) - step`` and the angle summed substep by substep, however the
        calls split the run: so a run read once per batch gives the same numbers, bit for
        bit, as one read every tick, and the plant may integrate lazily. A frame where the
        closed form does not hold (the rotor stops in it, discontinuous conduction) ends
        the frames taken; the caller steps it and a new run starts after it."""
        run = self._run
        if run is None or run[0] != duty:
            run = self._new_run(duty)
            if run is None:
                return 0
        p = self.params
        coast = duty <= 0.0
        d = 0.0 if coast else duty
        ke = p.ke_v_s_rad
        r_tot = p.r_ohm + d * d * p.supply_r_ohm
        v_drive = d * p.supply_v
        n_sub = self.n_sub
        h = self.frame_ns * 1e-9 / n_sub
        dcm_check = not coast and self.scheme is not EscScheme.COMPLEMENTARY
        n = n_frames * n_sub
        if run[1] == 0.0 and n <= self.SCALAR_RUN:
            return self._continue_run_scalar(run, n_frames, d, r_tot, v_drive, h, dcm_check)
        _, kind, c1, c2, step, phase = run
        w0 = self.omega
        x = np.empty(n)
        if kind == 0.0:
            x.fill(step)
            x[0] = phase * step
            np.multiply.accumulate(x, out=x)  # u_k, one product after the other
            phase_end = x
            w = x * c2
            np.subtract(c1, w, out=w)
            w /= np.subtract(1.0, x)
        else:
            x.fill(-step)
            x[0] = phase - step
            np.add.accumulate(x, out=x)  # arg_k, one step after the other
            phase_end = x
            w = np.tan(x)
            w *= c2
            w -= c1
        bad = w <= 0.0  # the rotor stops
        if kind != 0.0:
            bad |= x <= -math.pi / 2
        frames = n_frames
        hit = np.flatnonzero(bad)
        if hit.size:
            frames = int(hit[0]) // n_sub
        if dcm_check:  # continuous conduction at every point, the frame's start included
            emf = ke * np.concatenate(([w0], w))
            v_bus, v_f = p.supply_v, p.diode_drop_v
            i_all = (v_drive - emf) / r_tot
            dcm = d * d * p.pwm_period_for(self.scheme) * (v_bus + v_f) / (2.0 * p.l_h)
            i_dcm = dcm * np.maximum(v_bus - emf, 0.0) / (emf + v_f)
            hit = np.flatnonzero(i_all < i_dcm - 1e-12)
            if hit.size:
                first = int(hit[0])
                frames = min(frames, 0 if first == 0 else (first - 1) // n_sub)
        if frames == 0:
            return 0
        m = frames * n_sub
        w = w[:m]
        # the trajectory's rows, written in place
        out = np.empty((7, m))
        t_col, w_col, theta, i_w, i_bus, v_bus_out, duty_col = out
        w_col[:] = w
        if coast:
            i_w[:] = 0.0
            i_bus[:] = p.esc_quiescent_a
        else:
            np.multiply(w, ke, out=i_w)
            np.subtract(v_drive, i_w, out=i_w)
            i_w /= r_tot  # (E.4), (E.5)
            np.multiply(i_w, d, out=i_bus)
            i_bus += p.esc_quiescent_a
        # trapezoid rule, summed from theta_0 one substep after the other
        theta[1:] = w[:-1]
        theta[0] = w0
        theta += w
        theta *= 0.5 * h
        theta[0] += self.theta
        np.add.accumulate(theta, out=theta)
        ks = np.arange(self.k, self.k + frames) * self.frame_ns * 1e-9 + self.latency_ns * 1e-9
        if n_sub == 1:
            np.add(ks, h, out=t_col)
        else:
            t_col.reshape(frames, n_sub)[:] = ks[:, None] + np.arange(1, n_sub + 1) * h
        np.multiply(i_bus, p.supply_r_ohm, out=v_bus_out)
        np.subtract(p.supply_v, v_bus_out, out=v_bus_out)
        duty_col[:] = d
        self._traj.extend(out)
        self._run = (*run[:5], float(phase_end[m - 1]))
        self.omega, self.theta, self.i_w, self.duty = float(w[-1]), float(theta[-1]), \
            float(i_w[-1]), d
        self.i_bus, self.v_bus = float(i_bus[-1]), float(v_bus_out[-1])
        return frames

    def _continue_run_scalar(self, run: tuple[float, ...], n_frames: int, d: float,
                             r_tot: float, v_drive: float, h: float, dcm_check: bool) -> int:
        """``_continue_run`` for a few substeps of the ``u`` form in Python floats: the
        same operations in the same order as the numpy version, so the same numbers and
        the same frames taken."""
        p = self.params
        duty, _, w1, w2, q, u = run
        coast = duty <= 0.0
        ke, quiescent = p.ke_v_s_rad, p.esc_quiescent_a
        v_bus, v_f = p.supply_v, p.diode_drop_v
        dcm = d * d * p.pwm_period_for(self.scheme) * (v_bus + v_f) / (2.0 * p.l_h)

        def discontinuous(w: float) -> bool:
            emf = ke * w
            return (v_drive - emf) / r_tot < dcm * max(v_bus - emf, 0.0) / (emf + v_f) - 1e-12

        omega, theta = self.omega, self.theta
        if dcm_check and discontinuous(omega):
            return 0
        pts: list[tuple[float, ...]] = []
        n_sub, frames = self.n_sub, 0
        while frames < n_frames:
            t0 = (self.k + frames) * self.frame_ns * 1e-9 + self.latency_ns * 1e-9
            frame: list[tuple[float, ...]] = []
            for m in range(1, n_sub + 1):
                u = u * q
                w = (w1 - u * w2) / (1.0 - u)
                if w <= 0.0 or (dcm_check and discontinuous(w)):
                    break  # the closed form does not hold in this frame: step it
                theta = theta + (omega + w) * (0.5 * h)
                omega = w
                i_w = 0.0 if coast else (v_drive - w * ke) / r_tot
                i_bus = quiescent if coast else i_w * d + quiescent
                frame.append((t0 + m * h, w, theta, i_w, i_bus,
                              p.supply_v - i_bus * p.supply_r_ohm, d, u))
            if len(frame) < n_sub:
                break
            pts += frame
            frames += 1
        if frames == 0:
            return 0
        self._traj.pending.extend(pt[:7] for pt in pts)
        _, self.omega, self.theta, self.i_w, self.i_bus, self.v_bus, self.duty, u = pts[-1]
        self._run = (*run[:5], u)
        return frames

    def _integrate_frame(self, duty: float) -> None:
        p = self.params
        h = self.frame_ns * 1e-9 / self.n_sub
        t0 = self.k * self.frame_ns * 1e-9 + self.latency_ns * 1e-9
        coast = duty <= 0.0
        d = 0.0 if coast else duty
        allow_negative = self.scheme is EscScheme.COMPLEMENTARY and not coast
        r_tot = p.r_ohm + d * d * p.supply_r_ohm
        v_drive = d * p.supply_v
        kt, ke, kq, j = p.kt_nm_a, p.ke_v_s_rad, self._kq, p.j_kg_m2
        omega, theta, i_w = self.omega, self.theta, self.i_w
        # exact current step for frozen omega (C.1); read only with the inductance on
        decay = math.exp(-h * r_tot / p.l_h) if p.use_inductance else 0.0

        # diode scheme: below the back-emf the current is discontinuous; each PWM period it
        # rises from 0 during the on time and decays through the body diode (to 0) after
        v_bus, v_f = p.supply_v, p.diode_drop_v
        dcm_k = d * d * p.pwm_period_for(self.scheme) * (v_bus + v_f) / (2.0 * p.l_h)

        def current(w: float) -> float:
            if coast:
                return 0.0
            i = (v_drive - ke * w) / r_tot  # (E.4), (E.5), averaged over the PWM period
            if allow_negative:
                return i
            emf = ke * w
            i_dcm = dcm_k * (v_bus - emf) / (emf + v_f) if v_bus > emf else 0.0
            return i if i > i_dcm else i_dcm

        fr = p.friction_nm

        def f(w: float) -> float:
            drive = kt * current(w)  # (E.6)
            if w <= 0.0:  # at rest: friction holds the rotor until the motor overcomes it
                return (drive - fr) / j if drive > fr else 0.0
            return (drive - kq * w * w - fr) / j  # (E.7) plus bearing friction

        # With continuous current the ODE is a Riccati equation with constant coefficients,
        # J domega/dt = K_T (d V - K_E omega) / R - k_q omega^2 - friction (E.4-E.7),
        # solved exactly over each substep; the diode scheme's discontinuous conduction
        # and the rest state fall back to RK4.
        continuous = not p.use_inductance
        if coast:
            a_lin, b_lin = -fr / j, 0.0
        else:
            a_lin = (kt * v_drive / r_tot - fr) / j
            b_lin = kt * ke / (r_tot * j)
        c_sq = kq / j

        for m in range(1, self.n_sub + 1):
            if p.use_inductance:
                i_ss = (v_drive - ke * omega) / r_tot
                i_new = 0.0 if coast else i_ss + (i_w - i_ss) * decay
                if not allow_negative:  # the body diode blocks reverse current
                    i_new = max(i_new, current(omega) if i_new < i_ss else 0.0, 0.0)
                i_avg = 0.5 * (i_w + i_new)
                w_mid = omega + 0.5 * h * (kt * i_avg - kq * omega * abs(omega) - fr) / j
                omega_new = omega + h * (kt * i_avg - kq * w_mid * abs(w_mid) - fr) / j  # (E.7)
                omega_new = max(omega_new, 0.0)
                i_w = i_new
            else:
                omega_new = -1.0
                if continuous:
                    omega_new = _riccati(omega, h, a_lin, b_lin, c_sq)
                    # diode scheme: exact only while conduction stays continuous all along
                    if not allow_negative and not coast and (
                        (v_drive - ke * omega_new) / r_tot < current(omega_new) - 1e-12
                        or (v_drive - ke * omega) / r_tot < current(omega) - 1e-12
                    ):
                        omega_new = -1.0
                if omega_new < 0.0:
                    # RK4 on J domega/dt = K_T i - T(omega), i = (d V - K_E omega) / R
                    # (E.4-E.7)
                    k1 = f(omega)
                    k2 = f(omega + 0.5 * h * k1)
                    k3 = f(omega + 0.5 * h * k2)
                    k4 = f(omega + h * k3)
                    omega_new = omega + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
                    if omega_new < 0.0:
                        omega_new = 0.0  # friction stops the rotor; it never turns backwards
                i_w = current(omega_new)
            theta += 0.5 * h * (omega + omega_new)
            omega = omega_new
            self.omega, self.theta, self.i_w, self.duty = omega, theta, i_w, d
            self.i_bus = self._bus_current(d, i_w, omega) + p.esc_quiescent_a
            self.v_bus = p.supply_v - p.supply_r_ohm * self.i_bus
            self._append(t0 + m * h)


    def _bus_current(self, d: float, i_w: float, omega: float) -> float:
        """Supply current: d * i in continuous conduction; in discontinuous conduction
        (diode scheme) the winding current flows from the supply only in the on time."""
        if d <= 0.0:
            return 0.0
        p = self.params
        if self.scheme is EscScheme.COMPLEMENTARY:
            return d * i_w
        emf = p.ke_v_s_rad * omega
        i_peak = (p.supply_v - emf) * d * p.pwm_period_for(self.scheme) / p.l_h
        if i_peak <= 0.0 or i_w >= 0.5 * i_peak:
            return d * i_w  # continuous conduction
        return 0.5 * i_peak * d


def _riccati(w0: float, h: float, a: float, b: float, c: float) -> float:
    """Exact step of dw/dt = a - b w - c w^2 (c > 0) from w0 >= 0 over h, stopping at 0.

    Returns -1 when the rotor is at rest and the motor cannot overcome friction (the
    caller's RK4 handles the stiction logic).
    """
    if w0 <= 0.0 and a <= 0.0:
        return -1.0
    disc = b * b + 4.0 * a * c
    if disc > 0.0:
        s = math.sqrt(disc)
        w1 = (-b + s) / (2.0 * c)  # stable equilibrium
        w2 = (-b - s) / (2.0 * c)
        u = (w0 - w1) / (w0 - w2) * math.exp(-s * h)
        w = (w1 - u * w2) / (1.0 - u)
    else:  # no real equilibrium: the rotor decelerates on a tangent curve
        shift = b / (2.0 * c)
        g = math.sqrt(-disc) / (2.0 * c)
        arg = math.atan((w0 + shift) / g) - c * g * h
        w = g * math.tan(arg) - shift if arg > -math.pi / 2 else 0.0
    return w if w > 0.0 else 0.0


class EscFrameSource:
    """What the plant needs from an ESC model (see ``drivers.sim.esc.EscModel``)."""

    frame_ns: int

    def latch(self, k: int) -> float:  # pragma: no cover - interface only
        raise NotImplementedError

    def steady_frames(self, k: int, limit: int) -> int:  # pragma: no cover - interface only
        """How many frames from ``k`` on (at most ``limit``) latch the frame ``k``'s duty."""
        raise NotImplementedError
