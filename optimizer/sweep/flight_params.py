"""A design's flight model as plain numbers, and back.

A sweep's tasks carry numbers, not a catalog: a worker on another machine needs no
catalog file, and the numbers it flies are exactly the ones ``optimizer.flight.design.setup``
made (a float survives pickling and Parquet bit for bit).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from optimizer.flight.actuators import ActuatorModel
from optimizer.flight.vehicle import Vehicle

#: a plan's column of a constant's measured spread: ``std_`` + the quantity
#: (``optimizer.flight.uncertainty.QUANTITIES``), 0 where the constant is the model's
STD_PREFIX = "std_"

#: the principal inertias of ``Vehicle.inertia_kgm2``, one column each
INERTIA_COLUMNS = ("vehicle_inertia_roll_kgm2", "vehicle_inertia_pitch_kgm2",
                   "vehicle_inertia_yaw_kgm2")


def _vehicle_fields() -> list[str]:
    return [f.name for f in dataclasses.fields(Vehicle) if f.name != "inertia_kgm2"]


def _actuator_fields() -> list[str]:
    return [f.name for f in dataclasses.fields(ActuatorModel)]


def param_columns() -> tuple[str, ...]:
    """Every column :func:`params_of` fills, in order."""
    return (*(f"vehicle_{n}" for n in _vehicle_fields()), *INERTIA_COLUMNS,
            *(f"actuator_{n}" for n in _actuator_fields()))


def params_of(vehicle: Vehicle, actuator: ActuatorModel) -> dict[str, Any]:
    """The vehicle's and the actuator's fields, one column each."""
    out: dict[str, Any] = {f"vehicle_{n}": getattr(vehicle, n) for n in _vehicle_fields()}
    out.update(zip(INERTIA_COLUMNS, vehicle.inertia_kgm2, strict=True))
    out.update({f"actuator_{n}": getattr(actuator, n) for n in _actuator_fields()})
    return out


def flight_of(params: Mapping[str, Any]) -> tuple[Vehicle, ActuatorModel]:
    """The ``Vehicle`` and ``ActuatorModel`` of :func:`params_of`'s numbers (validated
    again by their own checks)."""
    ixx, iyy, izz = (float(params[c]) for c in INERTIA_COLUMNS)
    vehicle = Vehicle(**{n: params[f"vehicle_{n}"] for n in _vehicle_fields()},
                      inertia_kgm2=(ixx, iyy, izz))
    actuator = ActuatorModel(**{n: params[f"actuator_{n}"] for n in _actuator_fields()})
    return vehicle, actuator
