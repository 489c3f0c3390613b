"""Fly many designs at once: the figures of a batch flight, per design or its error.

A sweep flies hundreds of designs through the same maneuver; the scalar loop
(``maneuvers.fly``, plain floats, about 9 us a tick) pays Python's cost per design and
tick. ``fly_batch`` pays it once per tick for the whole batch (``batch_loop``, numpy over
the designs of a ``DesignBatch``) and gives each design the figures ``fly(vehicle,
actuator, man, gains=gains_for(actuator), record=False).figures`` gives: the same
floating-point operations in the same order, so the flights agree to the last bit where
numpy's sin, cos and arctan2 agree with Python's (tested: every figure within 1e-9).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from optimizer.flight.batch_designs import DesignBatch
from optimizer.flight.batch_loop import Trace, simulate
from optimizer.flight.maneuvers import DT_S, Maneuver, response_figures, trim_figures

__all__ = ["CHUNK", "DesignBatch", "fly_batch"]

#: Designs flown together at most; a larger batch flies in chunks of this size. Per
#: design and tick a flight keeps 9 bytes (the figure's signal and the saturation flag):
#: 150 MB for a 4 s maneuver of 4096 designs. Designs per CPU second still grow past it,
#: slowly (benchmarks/flight_batch_bench.py, docs/flight.md).
CHUNK = 4096


def fly_batch(batch: DesignBatch, man: Maneuver, dt: float = DT_S,
              chunk: int = CHUNK) -> list[dict[str, Any]]:
    """Fly ``man`` with every design of ``batch``; per design, in order, the figures dict
    ``fly(...).figures`` gives, or ``{"error": why}`` for a design that did not fly.

    Errors: a design whose numbers are invalid (``batch.errors``, not flown), and one whose
    flight diverged (its state became infinite or NaN, where the scalar loop raises or
    gives NaN figures). Neither stops the others; a caller can put ``row.get("error")``
    in an error column.
    """
    out: list[dict[str, Any]] = [{"error": e} if e else {} for e in batch.errors]
    valid = [i for i, e in enumerate(batch.errors) if not e]
    for start in range(0, len(valid), chunk):
        index = valid[start:start + chunk]
        part = batch if len(index) == len(batch) else batch.take(index)
        for i, fig in zip(index, _figures(part, man, simulate(part, man, dt)), strict=True):
            out[i] = fig
    return out


def _figures(batch: DesignBatch, man: Maneuver, trace: Trace) -> list[dict[str, Any]]:
    """Each design's figures from the stored ticks, as ``maneuvers.figures``."""
    final_ok = np.asarray(np.isfinite(trace.final).all(axis=0))
    out: list[dict[str, Any]] = []
    if man.axis == "hover":
        for i in range(len(batch)):
            if not final_ok[i]:
                out.append({"error": _diverged(None)})
                continue
            out.append(trim_figures(float(trace.hover_speed_rad_s[i]),
                                    float(trace.omega_min[i]),
                                    float(batch.omega_max_rad_s[i]), batch.n_rotors,
                                    float(batch.k_m[i]), float(abs(trace.final[2, i]))))
        return out
    finite = np.isfinite(trace.signal)
    for i in range(len(batch)):
        if not (final_ok[i] and finite[:, i].all()):
            bad = np.flatnonzero(~finite[:, i])
            out.append({"error": _diverged(float(trace.t[bad[0]]) if bad.size else None)})
            continue
        out.append(response_figures(man, trace.t, trace.signal[:, i], trace.saturated[:, i]))
    return out


def _diverged(t: float | None) -> str:
    when = f" from t = {t:.3f} s" if t is not None else ""
    return f"flight diverged: the state is not finite{when}"
