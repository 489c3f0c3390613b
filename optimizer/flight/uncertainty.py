"""Robust designs: flown samples of a design's measured constants, and their percentiles.

A measured actuator carries the uncertainty of its constants
(``optimizer.model.measured.MeasuredActuator`` ``*_std_*``): the standard uncertainty of
each constant's GUM budget where the store has one (the bench's calibration, noise, fit
and repeatability: ``analysis.metrology.constant_budgets``), else the spread of one
measurement (one edge of the step run, one speed level of the sweep). Flying a design M
times with its constants drawn from it shows what the measured constants leave open; the
figures are then summarised as 5th, 50th and 95th percentiles.

Distributions (one draw per sample and quantity, all independent):

* ``tau_up_s``, ``tau_down_s``, ``k_f_n_s2``, ``k_m_nm_s2``: log-normal with the nominal
  as mean and the std as standard deviation (sigma^2 = ln(1 + (std / nominal)^2),
  mu = ln(nominal) - sigma^2 / 2): always > 0, and the moments are the measured ones;
* ``latency_s``: normal around the nominal with the std, truncated to >= 0 (drawn by the
  inverse CDF, so nothing is rejected; a nominal more than 3 std above 0 keeps its mean
  within 0.5 % of a std of itself);
* a std of 0 (or none) gives the nominal itself in every sample.

Seeding: each design's generator is ``numpy.random.PCG64(SeedSequence(E))`` with E the
SHA-256 digest of the design's keys (``DESIGN_KEYS``: actuators, propeller, motor,
battery, series, parallel) and the user's seed. So a design's samples depend on nothing
else: not on the worker or chunk that flies it, not on the other designs or their order.
Row k of a design's normals feeds sample k, so raising M keeps the first samples.

Sample 0 is the nominal design (the constants as measured): its flight is the sweep's
nominal figure, and M samples cost M flights. A design without any uncertainty has M
identical samples; ``varies`` says which designs may be flown once and repeated.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.special import ndtr, ndtri

from optimizer.errors import RequestError
from optimizer.flight.actuators import ActuatorModel
from optimizer.flight.vehicle import Vehicle
from optimizer.model.measured import STD_OF, MeasuredActuator

__all__ = [
    "DESIGN_KEYS",
    "PERCENTILES",
    "QUANTITIES",
    "design_seed",
    "design_seeds",
    "draw",
    "draw_many",
    "nominal_of",
    "percentile_columns",
    "std_of",
    "varies",
    "with_sample",
]

#: What draws are made for, in the order of the columns of each design's normals (fixed:
#: reordering or inserting would change every stored draw).
QUANTITIES = ("tau_up_s", "tau_down_s", "latency_s", "k_f_n_s2", "k_m_nm_s2")
#: Drawn log-normal (positive); the others truncated normal (>= 0).
LOG_NORMAL = frozenset({"tau_up_s", "tau_down_s", "k_f_n_s2", "k_m_nm_s2"})
#: What names a design for its seed (a missing one counts as null: no pack of cells).
DESIGN_KEYS = ("actuators", "propeller", "motor", "battery", "series", "parallel")
#: The percentiles reported, and how (a flown sample's own value, no interpolation).
PERCENTILES = (5, 50, 95)
PERCENTILE_METHOD = "inverted_cdf"


def _absent(value: Any) -> bool:
    """None, NaN or pandas' NA (a design table's empty series/parallel cell)."""
    if value is None:
        return True
    try:
        return bool(value != value)  # NaN is the one value unequal to itself
    except TypeError:  # pandas.NA: its comparison has no truth value
        return True


def _canonical(design: Mapping[str, Any]) -> list[Any]:
    """The design's keys as JSON-stable values: counts as int, ids as str, absent as None."""
    missing = [k for k in DESIGN_KEYS[:4] if _absent(design.get(k))]
    if missing:
        raise RequestError(f"design {dict(design)!r}: no {', '.join(missing)} to seed its "
                           "samples with")
    out: list[Any] = []
    for key in DESIGN_KEYS:
        v = design.get(key)
        if v is None or _absent(v):
            out.append(None)
        elif key in ("propeller", "motor", "battery"):
            out.append(str(v))
        elif isinstance(v, bool | str) or int(v) != v:
            raise RequestError(f"design {dict(design)!r}: {key} must be a whole number")
        else:
            out.append(int(v))
    return out


def design_seed(design: Mapping[str, Any], seed: int = 0) -> np.random.SeedSequence:
    """The seed of one design's samples: SHA-256 of its ``DESIGN_KEYS`` and ``seed``."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise RequestError(f"seed must be a whole number >= 0, got {seed!r}")
    text = json.dumps([int(seed), _canonical(design)], separators=(",", ":"))
    digest = hashlib.sha256(text.encode()).digest()
    return np.random.SeedSequence(int.from_bytes(digest, "big"))


def design_seeds(designs: Iterable[Mapping[str, Any]], seed: int = 0
                 ) -> list[np.random.SeedSequence]:
    """``design_seed`` of each design (e.g. the rows of a sweep's design table)."""
    return [design_seed(d, seed) for d in designs]


def std_of(measured: MeasuredActuator | None) -> dict[str, float]:
    """The std of each of ``QUANTITIES`` a measured actuator carries (0 where none)."""
    if measured is None:
        return dict.fromkeys(QUANTITIES, 0.0)
    return {q: float(getattr(measured, STD_OF[q]) or 0.0) for q in QUANTITIES}


def nominal_of(vehicle: Vehicle, actuator: ActuatorModel) -> dict[str, float]:
    """The flown value of each of ``QUANTITIES``: the nominal the samples are drawn about
    (``optimizer.flight.design.setup`` has put the measured ones in)."""
    return {"tau_up_s": actuator.tau_up_s, "tau_down_s": actuator.tau_down_s,
            "latency_s": actuator.latency_s, "k_f_n_s2": vehicle.k_f, "k_m_nm_s2": vehicle.k_m}


def with_sample(vehicle: Vehicle, actuator: ActuatorModel, sample: Mapping[str, float]
                ) -> tuple[Vehicle, ActuatorModel]:
    """The design with one sample's constants (a quantity the sample lacks keeps its
    value). Fly it with the nominal design's gains: the controller is tuned to the
    measured constants, the built copy differs from them."""
    act = replace(actuator, **{q: float(sample[q]) for q in ("tau_up_s", "tau_down_s",
                                                               "latency_s") if q in sample})
    k_f, k_m = sample.get("k_f_n_s2"), sample.get("k_m_nm_s2")
    return vehicle.with_constants(k_f=None if k_f is None else float(k_f),
                                  k_m=None if k_m is None else float(k_m)), act


def _normals(seeds: Sequence[np.random.SeedSequence], m: int) -> np.ndarray:
    """Standard normals (designs, m, quantities): row k of a design feeds its sample k."""
    if not seeds:
        return np.empty((0, m, len(QUANTITIES)))
    return np.stack([np.random.Generator(np.random.PCG64(s)).standard_normal(
        (m, len(QUANTITIES))) for s in seeds])


def _log_normal(mean: np.ndarray, std: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Log-normal with the given mean and std from standard normals z."""
    s2 = np.log1p((std / mean) ** 2)
    return mean * np.exp(np.sqrt(s2) * z - 0.5 * s2)


def _truncated_normal(mean: np.ndarray, std: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Normal(mean, std) truncated to >= 0 by the inverse CDF of the standard normals z:
    each half through the tail the standard normal resolves well (ndtri near 0, not 1).
    z beyond +-37 (probability 1e-299) is clipped there, where ndtr still resolves it."""
    a = -mean / std  # the truncation point in std units (<= 0: the nominal is >= 0)
    z = np.clip(z, -37.0, 37.0)
    lower = ndtri(ndtr(a) + ndtr(z) * ndtr(-a))  # z < 0: from the lower tail
    upper = -ndtri(ndtr(-z) * ndtr(-a))  # z >= 0: through the upper tail's complement
    return np.maximum(mean + std * np.where(z < 0, lower, upper), 0.0)


def _column(values: Mapping[str, ArrayLike], name: str, n: int, what: str) -> np.ndarray:
    """One value per design of ``values[name]`` (a single number applies to all; none: 0)."""
    arr = np.asarray(values.get(name, 0.0), float)
    if arr.ndim == 0:
        return np.full(n, float(arr))
    if arr.shape != (n,):
        raise RequestError(f"{what} of {name}: {arr.size} values for {n} designs")
    return arr


def draw_many(nominal: Mapping[str, ArrayLike], std: Mapping[str, ArrayLike], m: int,
              seeds: Sequence[np.random.SeedSequence]) -> dict[str, np.ndarray]:
    """Samples (designs, m) of each quantity named in ``nominal``.

    ``nominal[q]`` and ``std[q]`` hold one value per design (one seed per design, from
    ``design_seed``); a quantity missing from ``std`` has none. Sample 0 is the nominal;
    a std of 0 gives the nominal in every sample (even a NaN nominal: "not measured" is
    passed through). A std > 0 needs a finite nominal > 0 (>= 0 for the latency)."""
    if isinstance(m, bool) or not isinstance(m, int | np.integer) or m < 1:
        raise RequestError(f"samples must be a whole number >= 1, got {m!r}")
    unknown = sorted(set(nominal) - set(QUANTITIES)) + sorted(set(std) - set(QUANTITIES))
    if unknown:
        raise RequestError(f"uncertain constants {', '.join(unknown)}: not one of "
                           f"{', '.join(QUANTITIES)}")
    n = len(seeds)
    z = _normals(seeds, int(m))
    out = {}
    for col, q in enumerate(QUANTITIES):
        if q not in nominal:
            continue
        mu = _column(nominal, q, n, "nominal")
        sd = _column(std, q, n, "std")
        if not np.all(np.isfinite(sd) & (sd >= 0)):
            raise RequestError(f"std of {q}: must be finite and >= 0, got "
                               f"{sd[~(np.isfinite(sd) & (sd >= 0))][0]:g}")
        spread = sd > 0
        ok = np.isfinite(mu) & ((mu > 0) | ((q == "latency_s") & (mu >= 0)))
        if np.any(spread & ~ok):
            raise RequestError(f"nominal {q} {mu[spread & ~ok][0]:g}: a std needs a finite "
                               f"nominal {'>= 0' if q == 'latency_s' else '> 0'}")
        values = np.repeat(mu[:, None], m, axis=1)
        if np.any(spread):
            pick = _log_normal if q in LOG_NORMAL else _truncated_normal
            values[spread] = pick(mu[spread, None], sd[spread, None], z[spread][:, :, col])
        values[:, 0] = mu  # sample 0: the nominal design
        out[q] = values
    return out


def draw(nominal: Mapping[str, float], std: Mapping[str, float], m: int,
         seed_key: np.random.SeedSequence) -> dict[str, np.ndarray]:
    """Samples (m,) of each quantity of one design (``draw_many`` for one design)."""
    many = draw_many({q: [v] for q, v in nominal.items()}, {q: [v] for q, v in std.items()},
                     m, [seed_key])
    return {q: v[0] for q, v in many.items()}


def varies(std: Mapping[str, ArrayLike]) -> np.ndarray:
    """Per design: whether any quantity has a std > 0 (else its M samples are alike, and
    one flight repeated M times gives the same percentiles)."""
    if not std:
        raise RequestError("varies: no std given (std_of gives one per quantity)")
    cols = [np.atleast_1d(np.asarray(v, float)) for v in std.values()]
    return np.any(np.stack(np.broadcast_arrays(*cols)) > 0, axis=0)


def percentile_columns(name: str, samples: ArrayLike, never: float = math.inf
                       ) -> dict[str, np.ndarray | float]:
    """``{name}_p05``, ``{name}_p50``, ``{name}_p95`` of the flown samples (last axis).

    Each percentile is one sample's value (numpy's ``inverted_cdf``: the smallest value
    with at least that share of the samples at or below it). A missing figure (None or
    NaN: a step that never rose or never settled) counts as ``never``: +inf for a time,
    so the 95th percentile is +inf exactly when more than 5 % of the samples never got
    there, the median when more than half did not. ``never=nan`` makes any missing
    sample give NaN percentiles. One design (samples (m,)) gives floats, several
    (designs, m) arrays."""
    x = np.asarray(samples, dtype=float)  # None -> NaN
    if x.ndim == 0 or x.shape[-1] == 0:
        raise RequestError(f"{name}: no samples to take percentiles of")
    x = np.where(np.isnan(x), never, x)
    q = np.percentile(x, PERCENTILES, axis=-1, method=PERCENTILE_METHOD)
    return {f"{name}_p{p:02d}": (float(v) if np.ndim(v) == 0 else v)
            for p, v in zip(PERCENTILES, q, strict=True)}
