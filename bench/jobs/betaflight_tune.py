"""Betaflight's PIDs scaled to the design, as a pilot would retune an over- or
under-powered quad: the same rate-loop crossover on every design.

Betaflight's rate PID acts on a plant whose gain is the design's tilt authority
(``optimizer.flight.plant.tilt_authority``: rad/s^2 per unit of mixer command). Its
default PIDs were seen to fly the thesis' P1+M2+B1 (``REFERENCE_AUTHORITY``); on a design
with k times that authority the same PIDs give k times the loop gain (a SizingLab pick
with thrust-to-weight 18: 4.2 x, the roll loop rang rail to rail and the pinned motors
climbed it past 30 m). Dividing every PID by k keeps the loop gain, so the crossover and
the margins, those of the reference: Betaflight's ``simplified_master_multiplier`` (one
factor on P, I, D, D max and feed-forward of every axis), set and applied before the
user's CLI lines, which may override it.
"""

from __future__ import annotations

from optimizer.flight.plant import tilt_authority
from optimizer.flight.vehicle import Vehicle

__all__ = ["MULTIPLIER_RANGE", "REFERENCE_AUTHORITY", "pid_scale", "tune_lines"]

#: tilt authority (rad/s^2 per unit command) of thesis-e P1+M2+B1, which Betaflight 4.6.0's
#: default PIDs fly (docs/flight.md)
REFERENCE_AUTHORITY = 395.0
#: simplified_master_multiplier's range in 4.6.0 (percent)
MULTIPLIER_RANGE = (10, 200)


def pid_scale(vehicle: Vehicle) -> int:
    """The master multiplier (percent) that gives ``vehicle`` the reference's loop gain."""
    pct = round(100.0 * REFERENCE_AUTHORITY / tilt_authority(vehicle))
    return max(MULTIPLIER_RANGE[0], min(MULTIPLIER_RANGE[1], pct))


def tune_lines(vehicle: Vehicle) -> list[tuple[str, str]]:
    """The CLI lines of the design's scaled PIDs, named as the bench's tune."""
    return [("tune", f"set simplified_master_multiplier = {pid_scale(vehicle)}"),
            ("tune", "simplified_tuning apply")]
