"""A batch of designs as numpy arrays: what ``batch_loop`` flies, built from the scalar
models (``Vehicle``, ``ActuatorModel``) or straight from arrays (a sweep needs no objects).

A batch holds designs of one rotor count and layout (the mixer's shape); everything else
may differ per design: mass, inertia, arm, rotor constants, actuator dynamics (time
constants, latency, ESC frame, levels, idle) and so the gains (the rule of
``controller.design_gains``, once per distinct actuator). Numbers a model would refuse
give that design an error, not the batch.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from optimizer.errors import RequestError
from optimizer.flight.actuators import (
    DEFAULT_FRAME_RATE_HZ,
    DEFAULT_IDLE_FRACTION,
    DEFAULT_LATENCY_S,
    DEFAULT_LEVELS,
    ActuatorModel,
)
from optimizer.flight.controller import Gains
from optimizer.flight.design import gains_for
from optimizer.flight.maneuvers import DT_S
from optimizer.flight.vehicle import FLIGHT_ACTUATORS, LAYOUTS, Vehicle

#: Per-design numbers of a batch, in the order of ``DesignBatch``'s fields.
_VEHICLE = ("mass_kg", "ixx", "iyy", "izz", "arm_m", "k_f", "k_m", "omega_max_rad_s",
            "gravity_m_s2")
_ACTUATOR = ("tau_up_s", "tau_down_s", "latency_s", "frame_s", "levels", "idle_fraction")


@dataclass(frozen=True)
class DesignBatch:
    """B designs of one rotor count and layout, each number an array of shape (B,), SI.

    ``errors[i]`` is "" for a design that can fly, else why not (its numbers are invalid:
    the check ``Vehicle`` and ``ActuatorModel`` make); ``fly_batch`` skips such designs.
    The gains are the rule's for the constructor's ``dt`` (as ``gains_for``).
    """

    n_rotors: int
    layout: str
    mass_kg: np.ndarray
    ixx: np.ndarray  # principal inertias, kg m^2: roll, pitch, yaw
    iyy: np.ndarray
    izz: np.ndarray
    arm_m: np.ndarray
    k_f: np.ndarray  # thrust per (rad/s)^2, (E.1)
    k_m: np.ndarray  # drag torque per (rad/s)^2, (E.2)-(E.3)
    omega_max_rad_s: np.ndarray
    gravity_m_s2: np.ndarray
    drag_n_s_m: np.ndarray
    tau_up_s: np.ndarray
    tau_down_s: np.ndarray
    latency_s: np.ndarray
    frame_s: np.ndarray
    levels: np.ndarray
    idle_fraction: np.ndarray
    k_p: np.ndarray  # gains of the rule (controller.design_gains)
    w_i: np.ndarray
    k_a: np.ndarray
    labels: tuple[str, ...]
    errors: tuple[str, ...]

    def __post_init__(self) -> None:
        size = len(self.labels)
        if len(self.errors) != size:
            raise ValueError(f"design batch: {len(self.errors)} errors for {size} labels")
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, np.ndarray):
                if value.shape != (size,):
                    raise ValueError(f"design batch: {f.name} has shape {value.shape}, "
                                     f"expected ({size},)")
                frozen = np.array(value, float)  # own copy: no design changes under a flight
                frozen.flags.writeable = False
                object.__setattr__(self, f.name, frozen)

    def __len__(self) -> int:
        return len(self.labels)

    def take(self, index: Sequence[int] | np.ndarray) -> DesignBatch:
        """The designs at ``index``, in that order."""
        index = np.asarray(index, int)
        values: dict[str, Any] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, np.ndarray):
                values[f.name] = value[index]
            elif isinstance(value, tuple):
                values[f.name] = tuple(value[i] for i in index)
            else:
                values[f.name] = value
        return DesignBatch(**values)

    @classmethod
    def from_models(cls, vehicles: Sequence[Vehicle], actuators: Sequence[ActuatorModel],
                    dt: float = DT_S) -> DesignBatch:
        """The batch of these (vehicle, actuator) pairs, with the gains ``gains_for`` gives
        (computed once per time constant and delay: designs often share an actuator)."""
        if len(vehicles) != len(actuators) or not vehicles:
            raise RequestError(f"design batch: needs as many actuators as vehicles (at least "
                               f"one), got {len(vehicles)} and {len(actuators)}")
        n, layout = vehicles[0].n_rotors, vehicles[0].layout
        for v in vehicles:
            if (v.n_rotors, v.layout) != (n, layout):
                raise RequestError(f"design batch: one rotor count and layout per batch, got "
                                   f"{n} {layout} and {v.n_rotors} {v.layout} ({v.label})")
        cache: dict[tuple[float, float], Gains] = {}
        gains = [_gains(a, dt, cache) for a in actuators]
        columns = {
            "mass_kg": [v.mass_kg for v in vehicles],
            "ixx": [v.inertia_kgm2[0] for v in vehicles],
            "iyy": [v.inertia_kgm2[1] for v in vehicles],
            "izz": [v.inertia_kgm2[2] for v in vehicles],
            "arm_m": [v.arm_m for v in vehicles],
            "k_f": [v.k_f for v in vehicles],
            "k_m": [v.k_m for v in vehicles],
            "omega_max_rad_s": [v.omega_max_rad_s for v in vehicles],
            "gravity_m_s2": [v.gravity_m_s2 for v in vehicles],
            "drag_n_s_m": [v.drag_n_s_m for v in vehicles],
            **{name: [getattr(a, name) for a in actuators] for name in _ACTUATOR},
            "k_p": [g.k_p for g in gains],
            "w_i": [g.w_i for g in gains],
            "k_a": [g.k_a for g in gains],
        }
        arrays = {k: np.array(v, float) for k, v in columns.items()}
        return cls(n, layout, **arrays, labels=tuple(v.label for v in vehicles),
                   errors=("",) * len(vehicles))

    @classmethod
    def from_arrays(cls, n_rotors: int, layout: str = "x", *, mass_kg: Any, ixx: Any,
                    iyy: Any, izz: Any, arm_m: Any, k_f: Any, k_m: Any,
                    omega_max_rad_s: Any, tau_up_s: Any, tau_down_s: Any,
                    gravity_m_s2: Any = 9.81, drag_n_s_m: Any = 0.0,
                    latency_s: Any = DEFAULT_LATENCY_S,
                    frame_s: Any = 1.0 / DEFAULT_FRAME_RATE_HZ, levels: Any = DEFAULT_LEVELS,
                    idle_fraction: Any = DEFAULT_IDLE_FRACTION,
                    labels: Sequence[str] | None = None, dt: float = DT_S,
                    gains: Any = None) -> DesignBatch:
        """A batch from numbers (scalars or arrays, broadcast to one length B), without
        building ``Vehicle`` objects; the defaults are ``Vehicle``'s and
        ``ActuatorModel``'s. A design with invalid numbers gets an error, not the batch.
        ``gains`` (B, 3) of (k_p, w_i, k_a) fly the designs with given gains instead of
        the rule's for their own actuator: a drawn sample of a design keeps the
        controller tuned for its nominal actuator, as a built vehicle would."""
        if layout not in LAYOUTS:
            raise RequestError(f"layout: expected one of {', '.join(LAYOUTS)}, got {layout!r}")
        if n_rotors not in FLIGHT_ACTUATORS:
            raise RequestError(f"actuators: the flight model flies N = 4, 6 or 8 (alternating "
                               f"spin), got {n_rotors}")
        given = {"mass_kg": mass_kg, "ixx": ixx, "iyy": iyy, "izz": izz, "arm_m": arm_m,
                 "k_f": k_f, "k_m": k_m, "omega_max_rad_s": omega_max_rad_s,
                 "gravity_m_s2": gravity_m_s2, "drag_n_s_m": drag_n_s_m,
                 "tau_up_s": tau_up_s, "tau_down_s": tau_down_s, "latency_s": latency_s,
                 "frame_s": frame_s, "levels": levels, "idle_fraction": idle_fraction}
        try:
            arrays = dict(zip(given, np.broadcast_arrays(
                *(np.atleast_1d(np.asarray(v, float)) for v in given.values())), strict=True))
        except ValueError as e:
            raise RequestError(f"design batch: the numbers do not broadcast to one length "
                               f"({e})") from None
        size = arrays["mass_kg"].size
        names = tuple(labels) if labels is not None else tuple(str(i) for i in range(size))
        if len(names) != size:
            raise RequestError(f"design batch: {len(names)} labels for {size} designs")
        errors = _errors(n_rotors, layout, arrays, names)
        valid = np.array([not e for e in errors], bool)
        if gains is not None:
            gains = np.array(gains, float).reshape(-1, 3)
            if gains.shape[0] != size:
                raise RequestError(f"design batch: {gains.shape[0]} gains for {size} designs")
        else:
            gains = np.full((size, 3), np.nan)
        need = valid & np.isnan(gains).any(axis=1)
        if need.any():  # the rule once per distinct actuator
            table = np.stack([arrays[name][need] for name in _ACTUATOR], axis=1)
            kinds, which = np.unique(table, axis=0, return_inverse=True)
            cache: dict[tuple[float, float], Gains] = {}
            per_kind = []
            for up, down, latency, frame, levels, idle in kinds.tolist():
                g = _gains(ActuatorModel(up, down, latency, frame, int(levels), idle), dt,
                           cache)
                per_kind.append((g.k_p, g.w_i, g.k_a))
            gains[need] = np.array(per_kind)[which.ravel()]
        return cls(n_rotors, layout, **arrays, k_p=gains[:, 0], w_i=gains[:, 1],
                   k_a=gains[:, 2], labels=names, errors=tuple(errors))


def _gains(actuator: ActuatorModel, dt: float, cache: dict[tuple[float, float], Gains]
           ) -> Gains:
    """``gains_for`` once per (mean time constant, delay)."""
    key = (actuator.tau_mean_s, actuator.effective_delay_s(dt))
    if key not in cache:
        cache[key] = gains_for(actuator, dt)
    return cache[key]


def _errors(n_rotors: int, layout: str, arrays: dict[str, np.ndarray],
            labels: Sequence[str]) -> list[str]:
    """Per design, "" or why its numbers cannot fly: the models' own checks (their
    message), run only on the designs a vectorised pre-check flags."""
    a = arrays
    positive = np.logical_and.reduce([np.isfinite(a[k]) & (a[k] > 0) for k in
                                      (*_VEHICLE, "tau_up_s", "tau_down_s")])
    ok = (positive & np.isfinite(a["drag_n_s_m"])
          & np.isfinite(a["latency_s"]) & (a["latency_s"] >= 0)
          & np.isfinite(a["frame_s"]) & (a["frame_s"] >= 0)
          & (a["levels"] >= 2) & (a["levels"] == np.round(a["levels"]))
          & (a["idle_fraction"] >= 0) & (a["idle_fraction"] < 1))
    errors = [""] * ok.size
    for i in np.flatnonzero(~ok).tolist():
        v = {k: float(x[i]) for k, x in a.items()}
        try:
            Vehicle(v["mass_kg"], (v["ixx"], v["iyy"], v["izz"]), n_rotors, v["arm_m"],
                    layout, v["k_f"], v["k_m"], v["omega_max_rad_s"], v["gravity_m_s2"],
                    v["drag_n_s_m"], labels[i])
            levels = int(v["levels"]) if math.isfinite(v["levels"]) else 0
            ActuatorModel(v["tau_up_s"], v["tau_down_s"], v["latency_s"], v["frame_s"],
                          levels, v["idle_fraction"], source=f"design {labels[i]}")
            if levels != v["levels"]:
                raise RequestError(f"actuator (design {labels[i]}): levels must be a whole "
                                   f"number, got {v['levels']!r}")
            if not math.isfinite(v["drag_n_s_m"]):
                raise RequestError(f"vehicle {labels[i]}: drag_n_s_m must be finite, got "
                                   f"{v['drag_n_s_m']!r}")
            raise RequestError(f"design {labels[i]}: numbers out of range")
        except RequestError as e:
            errors[i] = str(e)
    return errors
