"""The columns of a sweep's output: one row per design.

Design keys and id; the static model's numbers (every ``METRIC_KEYS`` metric of the
design grid and the full-throttle thrust-to-weight); whether the design can hover and,
where not, why; the actuator flown; per maneuver its figures
(``<maneuver>_rise_time_ms``, ...; null where a figure is not defined, e.g. a gust has
no rise time) and, for a robust sweep, their percentiles over the samples; ``error``
(null when the design flew). The order and the types are fixed here, so every chunk's
part has the same schema whatever its values.
"""

from __future__ import annotations

from collections.abc import Sequence

from optimizer.flight.uncertainty import PERCENTILES
from optimizer.model.grid import METRIC_KEYS
from optimizer.sweep.keys import DESIGN_KEYS

#: figures of every maneuver (``optimizer.flight.maneuvers.figures``)
FIGURES: tuple[str, ...] = ("rise_time_ms", "overshoot_pct", "settling_time_ms",
                            "saturation_pct")

#: the static numbers a row carries from the design grid
STATIC: tuple[str, ...] = (*METRIC_KEYS, "thrust_to_weight")

#: value kinds: "str", "int", "float", "bool" (the Parquet writer maps them to types)
KEY_KINDS: dict[str, str] = {"actuators": "int", "propeller": "str", "motor": "str",
                             "battery": "str", "series": "int", "parallel": "int"}


def figure_names(maneuver: str) -> tuple[str, ...]:
    """The figures a maneuver's row columns hold: the four of every maneuver and the
    fifth it has (how far a gust tilts; the error left at the end of a step)."""
    return (*FIGURES, "peak_tilt_deg" if maneuver == "gust" else "final_error_pct")


def figure_columns(maneuvers: Sequence[str]) -> list[str]:
    """``<maneuver>_<figure>`` for every maneuver flown, in order."""
    return [f"{m}_{f}" for m in maneuvers for f in figure_names(m)]


def spread_figures(maneuver: str) -> tuple[str, ...]:
    """The figures a robust sweep (``--samples``) gives percentiles of: the four of a
    step, or how long a gust disturbs, how hard the mixer saturates and how far it tilts."""
    if maneuver == "gust":
        return ("settling_time_ms", "saturation_pct", "peak_tilt_deg")
    return FIGURES


def percentile_columns(maneuvers: Sequence[str]) -> list[str]:
    """``<maneuver>_<figure>_p05/_p50/_p95`` of every spread figure, in order."""
    return [f"{m}_{f}_p{p:02d}" for m in maneuvers for f in spread_figures(m)
            for p in PERCENTILES]


def columns(maneuvers: Sequence[str], samples: int = 1) -> list[tuple[str, str]]:
    """(name, kind) of every column of a sweep that flies ``maneuvers`` (with
    ``samples`` > 1: the percentiles too), in order."""
    return [
        ("design_id", "str"),
        *((k, KEY_KINDS[k]) for k in DESIGN_KEYS),
        *((k, "float") for k in STATIC),
        ("can_hover", "bool"),
        ("note", "str"),  # why the design cannot hover (null when it can)
        ("tau_up_ms", "float"),  # the actuator flown: model (E.35), measured or a step run
        ("tau_down_ms", "float"),
        ("latency_ms", "float"),
        *((c, "float") for c in figure_columns(maneuvers)),
        *((c, "float") for c in (percentile_columns(maneuvers) if samples > 1 else ())),
        ("error", "str"),
    ]
