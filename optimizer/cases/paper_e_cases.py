"""Paper E's three test cases (section 4; Tables E.8-E.10), as ``optimize --paper-e-cases``
and the demo run them: one home, so both always solve the same cases."""

from __future__ import annotations

__all__ = ["PAPER_E_CASES"]

#: Paper E section 4: (case, title, objective, payload kg).
PAPER_E_CASES: tuple[tuple[str, str, str, float], ...] = (
    ("I", "Test Case I: longest flight time, no payload (Table E.8)", "flight-time", 0.0),
    ("II", "Test Case II: longest flight time, 1.5 kg payload (Table E.9)", "flight-time", 1.5),
    ("III", "Test Case III: fastest motor response, no payload (Table E.10)", "time-constant", 0.0),
)
