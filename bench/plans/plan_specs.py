"""Plans by name: the propulsion sequences the CLI commands and the console both build.

``rotorbench step``/``sweep`` and the console's plan tab ask for the same things (Paper C
Step 1 or Step 2, a sequence file, the slow sweep, with a few tightened limits); they get
them here, so neither side builds a plan by calling the other.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

from bench.errors import RigError
from bench.plans.sequences import Sequence, load_sequence
from bench.plans.stand_sequences import step1, step2, sweep

__all__ = ["named_step_sequence", "plan_sequence", "sweep_sequence", "with_limits"]


def with_limits(seq: Sequence, extra: Mapping[str, float]) -> Sequence:
    """``seq`` with ``extra`` tighter limits (checked against the rig when it runs)."""
    if not extra:
        return seq
    return replace(seq, limits={**seq.limits, **extra})


def named_step_sequence(sequence: str, repeats: int = 20, hold_s: float = 0.5,
                        limits: Mapping[str, float] | None = None) -> Sequence:
    """``step1``/``step2`` (Paper C), or a sequence file (.json/.toml) by path."""
    if sequence in ("step1", "step2"):
        maker = step1 if sequence == "step1" else step2
        seq = maker(repeats=repeats, hold_s=hold_s)
    else:
        seq = load_sequence(Path(sequence))
    return with_limits(seq, limits or {})


def sweep_sequence(start_us: float = 1100.0, end_us: float = 1900.0, duration_s: float = 20.0,
                   limits: Mapping[str, float] | None = None) -> Sequence:
    """The slow static-map sweep (Paper C section 4.4) with tighter ``limits``."""
    return with_limits(sweep(start_us, end_us, duration_s), limits or {})


def plan_sequence(spec: Mapping[str, Any]) -> Sequence:
    """The sequence a console plan request names: ``{"plan": "step1"|"step2"|"sweep"|"file",
    ...}`` with the same settings and defaults as the step and sweep commands."""
    kind = str(spec.get("plan", ""))
    if kind in ("step1", "step2", "file"):
        sequence = str(spec.get("path", "")) if kind == "file" else kind
        if kind == "file" and not sequence:
            raise RigError("plan file: choose a .json or .toml sequence file first")
        return named_step_sequence(sequence, int(spec.get("repeats", 20)),
                                   float(spec.get("hold_s", 0.5)))
    if kind == "sweep":
        return sweep_sequence(float(spec.get("start_us", 1100.0)),
                              float(spec.get("end_us", 1900.0)),
                              float(spec.get("duration_s", 20.0)))
    raise RigError(f"plan {kind!r}: expected step1, step2, sweep or file")
