"""Run several filters on the same samples, score them as BROAD does, plot their errors."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from analysis import quaternion as quat
from analysis.attitude_filters import PEERS, FilterRun, available, run_filter
from analysis.attitude_scoring import AttitudeScore, error_angles, error_quaternion_earth, score
from analysis.figures import _save
from analysis.imu_recording import ImuRecording

__all__ = ["COMPARE_PROJECT", "DEVICE_LABEL", "ComparisonRow", "compare", "error_figure",
           "score_run"]

#: the row of the attitude the device under test reported itself (kind ``device``)
DEVICE_LABEL = "device (own attitude)"
# the project's rows of a comparison: the default in 9D (if there is a magnetometer) and 6D
COMPARE_PROJECT = (("default", False), ("default", True), ("default-causal", True),
                   ("paper-b", True), ("paper-b-printed", True))


@dataclass(frozen=True)
class ComparisonRow:
    """One filter's scores on one recording; ``kind`` is ``project`` or ``peer``."""

    label: str
    kind: str
    run: FilterRun
    score: AttitudeScore

    def as_dict(self) -> dict[str, object]:
        return {"filter": self.label, "kind": self.kind,
                "mode": "9D" if self.run.nine_d else "6D",
                "seconds": round(self.run.seconds, 4),
                "cpu_seconds": round(self.run.cpu_seconds, 4), **self.score.as_deg()}


def score_run(rec: ImuRecording, run: FilterRun) -> AttitudeScore:
    """BROAD scores of one run; a 6D run is scored after its constant heading offset."""
    if rec.ref_quat is None:
        raise ValueError(f"{rec.source} has no reference orientation to score against")
    return score(run.quat, rec.ref_quat, rec.movement, remove_heading_offset=not run.nine_d)


def _label(name: str, run: FilterRun) -> str:
    if name in PEERS:
        return name
    return f"{name} ({'9D' if run.nine_d else '6D'})"


def compare(rec: ImuRecording, peers: bool | Sequence[str] = True) -> list[ComparisonRow]:
    """The project's filters (6D and 9D where possible), the available peers and, where
    the recording has it, the attitude the device reported itself (kind ``device``: a
    flight controller's MSP_ATTITUDE, scored like a 6D peer).

    ``peers``: all (``True``), none (``False``) or these names of :data:`PEERS`, in the
    table's order.
    """
    rows: list[ComparisonRow] = []
    seen: set[tuple[str, bool]] = set()
    for name, six_d in COMPARE_PROJECT:
        run = run_filter(name, rec, six_d=six_d)
        if (name, run.nine_d) in seen:  # no magnetometer: 6D and "9D" are the same run
            continue
        seen.add((name, run.nine_d))
        rows.append(ComparisonRow(_label(name, run), "project", run, score_run(rec, run)))
    if peers is not False:
        wanted = set(PEERS if peers is True else peers)
        unknown = wanted - set(PEERS)
        if unknown:
            raise ValueError(f"unknown peer {sorted(unknown)[0]!r}; known: {', '.join(PEERS)}")
        for name in PEERS:
            if name in wanted and available(name, rec):
                run = run_filter(name, rec)
                rows.append(ComparisonRow(name, "peer", run, score_run(rec, run)))
    if rec.device_quat is not None:
        run = FilterRun(DEVICE_LABEL, quat.normalize(rec.device_quat), False, 0.0, 0.0)
        rows.append(ComparisonRow(DEVICE_LABEL, "device", run, score_run(rec, run)))
    return rows


def error_figure(rec: ImuRecording, rows: list[ComparisonRow], path: str | Path,
                 title: str = "") -> Path:
    """PNG: inclination and heading error (deg) over time of every row, movement shaded."""
    path = Path(path)
    fig, axes = plt.subplots(2, 1, figsize=(11, 6.5), sharex=True)
    t = rec.t_s - rec.t_s[0]
    colors = plt.cm.tab20(np.linspace(0.0, 1.0, 20))
    q_ref = rec.ref_quat
    if q_ref is None:
        raise ValueError(f"{rec.source} has no reference orientation to compare against")
    for i, row in enumerate(rows):
        qe = row.run.quat
        if not row.run.nine_d and row.score.heading_offset_rad:
            qe = quat.multiply(quat.from_axis_angle([0, 0, 1], -row.score.heading_offset_rad),
                               qe)
        _, heading, incl = error_angles(error_quaternion_earth(qe, q_ref))
        style = "-" if row.kind == "project" else ":"
        c = colors[(2 * i) % 20 + (2 * i) // 20 % 2]
        axes[0].plot(t, np.degrees(incl), style, lw=0.8, color=c, label=row.label)
        axes[1].plot(t, np.degrees(heading), style, lw=0.8, color=c, label=row.label)
    if rec.movement is not None:
        for ax in axes:
            ax.fill_between(t, 0, 1, where=~rec.movement, color="0.9",
                            transform=ax.get_xaxis_transform(), label=None)
    axes[0].set_ylabel("inclination error (deg)")
    axes[1].set_ylabel("heading error (deg)\n(6D: offset removed)")
    axes[1].set_xlabel("time (s); grey: not scored (no movement)")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, ncol=3, loc="upper right")
    axes[0].set_title(title or Path(rec.source).name)
    fig.tight_layout()
    return _save(fig, path)

