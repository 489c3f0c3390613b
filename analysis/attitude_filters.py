"""The project's orientation filters and the published peers, behind one call.

Every filter takes an :class:`~analysis.imu_recording.ImuRecording` (SI units) and returns
scalar-first quaternions, sensor to earth, ENU (z up; x east in 9D). Filters:

* ``default``: VQF (Laidig & Seel, "VQF: Highly Accurate IMU Orientation Estimation with
  Bias Estimation and Magnetic Disturbance Rejection", Information Fusion 91, 2023; the
  ``vqf`` package, MIT, C++ core) run offline over the whole file (``offlineVQF``: the
  forward-backward form, bias estimated from all rests and motion). It does everything
  the issue asks of a default filter (rest detection and gyro bias, accelerometer
  disturbance rejection, magnetometer heading with disturbance detection, a 6D mode), it
  is the best published result on BROAD (by the benchmark's authors), maintained, and
  fast. Writing our own would only reproduce it less well. ``default-causal`` is the
  online ``VQF`` class, sample by sample, the form a live bench would run. With a
  magnetometer the default gives the 9D estimate, otherwise (or with ``six_d``) the 6D.
* ``paper-b``: Paper B's trig-free complementary filter (B.12-B.20) with the accelerometer
  low-passed in the earth frame before its direction is taken, as VQF does
  (:mod:`analysis.attitude_inertial`): robust to long lively motion (a sensor swung and
  translated), where the printed correction tilts by 10-20°. Gyro minus a bias
  estimated at rest (:mod:`analysis.gyro_bias`). 6D only, as in the paper.
* ``paper-b-printed``: Paper B's correction as printed, each sample's normalised
  accelerometer blended with P_err (:func:`analysis.attitude.estimate_attitude`, by default
  ``tilt="estimate"``, valid in every orientation), same bias; what ``paper-b`` was before
  its earth-frame low-pass.

Peers (the ``imu`` extra), defaults of their packages: ``vqf-6d``/``vqf-9d`` (online VQF),
``vqf-offline-6d``/``-9d``, ``madgwick-6d``/``-9d`` and ``mahony-6d``/``-9d`` (``ahrs``,
Mayitzin). ahrs' Madgwick works in a north-west-up earth frame with a magnetometer; it is
turned into ENU by a 90° turn about z, as BROAD's example code does.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from analysis import quaternion as quat
from analysis.attitude import estimate_attitude, lowpass_acc
from analysis.attitude_inertial import estimate_attitude_inertial
from analysis.extras import import_extra
from analysis.gyro_bias import gyro_bias_at_rest
from analysis.imu_recording import ImuRecording, uniform_grid

__all__ = [
    "PAPER_B_ACC_TAU_S",
    "PAPER_B_EARTH_LP_S",
    "PAPER_B_PRINTED_TAU_S",
    "PAPER_B_TAU_S",
    "PEERS",
    "PROJECT_FILTERS",
    "FilterRun",
    "available",
    "paper_b",
    "paper_b_printed",
    "run_filter",
]

Array = NDArray[np.float64]
# The printed form's time constant τ = t_s / P_err. Paper B: P_err = 0.002 at 400 Hz
# (1.25 s). With the gyro bias re-estimated at rest the gyro drifts less, so the
# accelerometer may be trusted less: 3 s, VQF's default τ_acc; on the simulated hexapod
# motion 2.5-5 s are equally good (docs/attitude.md).
PAPER_B_PRINTED_TAU_S = 3.0
# paper-b: blend τ and earth-frame low-pass τ, two first-order poles (VQF: a 3 s
# second-order low-pass). Measured on trial 07, its BROAD-shaped variants and the
# simulations (docs/attitude.md, benchmarks/attitude_paper_b_tuning.py): 3 s + 3 s is best
# on the lively variants but worse than the printed form on the simulated hexapod and
# tour; 1.5 s + 1.5 s is within the bound everywhere and better than the printed form on
# every recording.
PAPER_B_TAU_S = 1.5
PAPER_B_EARTH_LP_S = 1.5
# Accelerometer low-pass (B.28) ahead of the normalisation: G_a = exp(-t_s/τ_a). A zero-mean
# vibration does not average out after normalising (|g + v| rectifies it into a tilt); 5 ms
# (G_a = 0.5 at 286 Hz) removed that on the vibration variant of BROAD 07 (2.20° -> 1.66°)
# and cost nothing on trial 07 (1.63° -> 1.64°); 0.3-0.5 were equal, 0.8 cost 0.2°.
PAPER_B_ACC_TAU_S = 0.005
_NWU_TO_ENU = np.array([math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)])  # 90° about z


@dataclass(frozen=True)
class FilterRun:
    """One filter's output on one recording: quaternions, 6D/9D, wall and CPU time (s).

    On a shared machine the wall time includes waiting for a core; the CPU time of this
    process is the filter's own cost.
    """

    name: str
    quat: Array
    nine_d: bool
    seconds: float
    cpu_seconds: float = float("nan")


def _c(x: Array) -> Array:
    return np.ascontiguousarray(x, dtype=float)


def _mag(rec: ImuRecording) -> Array:
    """The magnetometer samples a 9D filter reads (``run_filter`` checked they exist)."""
    if rec.mag_ut is None:
        raise ValueError(f"{rec.source} has no magnetometer samples")
    return _c(rec.mag_ut)


def _ts(rec: ImuRecording) -> float:
    return 1.0 / rec.rate_hz


def _offline_vqf(rec: ImuRecording, nine_d: bool) -> Array:
    vqf = import_extra("vqf", "imu", "the default filter (VQF)")
    mag = _mag(rec) if nine_d else None
    out = vqf.offlineVQF(_c(rec.gyro_rad_s), _c(rec.acc_m_s2), mag, _ts(rec))
    return out["quat9D" if nine_d else "quat6D"]


def _online_vqf(rec: ImuRecording, nine_d: bool) -> Array:
    vqf = import_extra("vqf", "imu", "VQF")
    f = vqf.VQF(_ts(rec))
    if nine_d:
        return f.updateBatch(_c(rec.gyro_rad_s), _c(rec.acc_m_s2), _mag(rec))["quat9D"]
    return f.updateBatch(_c(rec.gyro_rad_s), _c(rec.acc_m_s2))["quat6D"]


def _bias(rec: ImuRecording, bias_seconds: float | None) -> Array:
    """The gyro bias per sample: estimated at every rest, or Paper B's fixed bias (the mean
    of the first ``bias_seconds``)."""
    t, gyro = rec.t_s, rec.gyro_rad_s
    if bias_seconds is not None:
        return np.broadcast_to(gyro[t <= t[0] + bias_seconds].mean(axis=0), gyro.shape)
    return gyro_bias_at_rest(t, gyro, rec.acc_m_s2)[0]


def paper_b(rec: ImuRecording, tau_s: float = PAPER_B_TAU_S, gain: float | None = None,
            bias_seconds: float | None = None, acc_lowpass: float | None = None,
            earth_lowpass_s: float = PAPER_B_EARTH_LP_S) -> Array:
    """Paper B's filter with the accelerometer low-passed in the earth frame (VQF's way).

    ``gain`` (P_err per sample) defaults to ``t_s / tau_s``; ``earth_lowpass_s`` is the
    earth-frame low-pass (:func:`analysis.attitude_inertial.estimate_attitude_inertial`).
    The bias as in :func:`paper_b_printed`. ``acc_lowpass`` is G_a of (B.28) on the body
    accelerometer, off by default: the earth-frame low-pass is linear, a vibration averages
    out in it without rectifying.
    """
    if gain is None:
        gain = min(1.0, _ts(rec) / tau_s)  # P_err = t_s / τ
    acc = rec.acc_m_s2 if not acc_lowpass else lowpass_acc(rec.acc_m_s2, acc_lowpass)
    return estimate_attitude_inertial(rec.t_s, rec.gyro_rad_s - _bias(rec, bias_seconds), acc,
                                      gain=gain, tau_lp_s=earth_lowpass_s)


def paper_b_printed(rec: ImuRecording, tau_s: float = PAPER_B_PRINTED_TAU_S,
                    gain: float | None = None, bias_seconds: float | None = None,
                    acc_lowpass: float | None = None, tilt: str = "estimate") -> Array:
    """Paper B's printed correction, valid in every orientation, on the gyro with its bias
    removed: each sample's normalised accelerometer blended with P_err (B.15-B.20).

    ``gain`` (P_err per sample) defaults to ``t_s / tau_s``. The bias is estimated at every
    rest unless ``bias_seconds`` asks for Paper B's fixed bias, the mean of the first S s.
    ``acc_lowpass`` is G_a of (B.28), default ``exp(-t_s / PAPER_B_ACC_TAU_S)``; ``tilt`` as
    in :func:`estimate_attitude`.
    """
    if gain is None:
        gain = min(1.0, _ts(rec) / tau_s)  # P_err = t_s / τ
    if acc_lowpass is None:
        acc_lowpass = math.exp(-_ts(rec) / PAPER_B_ACC_TAU_S)  # (B.28) as a time constant
    return estimate_attitude(rec.t_s, rec.gyro_rad_s - _bias(rec, bias_seconds), rec.acc_m_s2,
                             gain=gain, acc_lowpass=acc_lowpass, tilt=tilt)


def _ahrs(name: str, rec: ImuRecording, nine_d: bool) -> Array:
    filters = import_extra("ahrs.filters", "imu", f"the {name} peer (ahrs)")
    cls = getattr(filters, name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        q = cls(gyr=_c(rec.gyro_rad_s), acc=_c(rec.acc_m_s2),
                mag=_mag(rec) if nine_d else None, frequency=rec.rate_hz).Q
    if nine_d and name == "Madgwick":  # ahrs Madgwick MARG: x north, z up (NWU)
        q = quat.multiply(_NWU_TO_ENU, q)
    return q


Runner = Callable[[ImuRecording, bool], Array]


def _fixed_rate(runner: Runner) -> Runner:
    """A filter with one sample time, run on a uniform grid if the recording is not uniform
    (:func:`analysis.imu_recording.uniform_grid`), its output taken back to the rows."""
    def run(rec: ImuRecording, nine_d: bool) -> Array:
        grid = uniform_grid(rec)
        if grid is None:
            return runner(rec, nine_d)
        q = quat.normalize(np.asarray(runner(grid.rec, nine_d), dtype=float))
        return quat.nlerp(q[grid.idx], q[grid.idx + 1], grid.u)
    return run


_offline = _fixed_rate(_offline_vqf)
_online = _fixed_rate(_online_vqf)
_madgwick = _fixed_rate(lambda rec, nine: _ahrs("Madgwick", rec, nine))
_mahony = _fixed_rate(lambda rec, nine: _ahrs("Mahony", rec, nine))
# name -> (runner, needs a magnetometer); paper-b* integrate each sample's own interval
PROJECT_FILTERS: dict[str, tuple[Runner, bool | None]] = {
    "default": (_offline, None),
    "default-causal": (_online, None),
    "paper-b": (lambda rec, nine: paper_b(rec), False),
    "paper-b-printed": (lambda rec, nine: paper_b_printed(rec), False),
}
PEERS: dict[str, tuple[Runner, bool]] = {
    "vqf-6d": (_online, False),
    "vqf-9d": (_online, True),
    "vqf-offline-6d": (_offline, False),
    "vqf-offline-9d": (_offline, True),
    "madgwick-6d": (_madgwick, False),
    "madgwick-9d": (_madgwick, True),
    "mahony-6d": (_mahony, False),
    "mahony-9d": (_mahony, True),
}


def available(name: str, rec: ImuRecording) -> bool:
    """Whether ``name`` can run on ``rec`` (9D peers need a magnetometer)."""
    _, mode = {**PROJECT_FILTERS, **PEERS}[name]
    return not (mode is True and rec.mag_ut is None)


def run_filter(name: str, rec: ImuRecording, six_d: bool = False) -> FilterRun:
    """Run one project filter or peer by name and time it (wall clock)."""
    table = {**PROJECT_FILTERS, **PEERS}
    if name not in table:
        raise ValueError(f"unknown filter {name!r}; known: {', '.join(table)}")
    runner, mode = table[name]
    nine_d = (rec.mag_ut is not None and not six_d) if mode is None else mode
    if nine_d and rec.mag_ut is None:
        raise ValueError(f"filter {name} needs magnetometer samples; {rec.source} has none")
    start, cpu = time.perf_counter(), time.process_time()
    q = np.asarray(runner(rec, nine_d), dtype=float)
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    return FilterRun(name, quat.normalize(q), nine_d, seconds, cpu)
