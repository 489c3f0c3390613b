"""Moved to :mod:`drivers.hexapod_motions` (the motions are device-free); kept for imports."""

from drivers.hexapod_motions import (
    DOF,
    Motion,
    Phase,
    Term,
    acc_motion,
    gyro_sines,
    lever_arm_motion,
    paper_a_protocol,
    static_hold,
    verification_motion,
)

__all__ = [
    "DOF",
    "Motion",
    "Phase",
    "Term",
    "acc_motion",
    "gyro_sines",
    "lever_arm_motion",
    "paper_a_protocol",
    "static_hold",
    "verification_motion",
]
