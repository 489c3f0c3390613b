"""The column separator and decimal mark of a CSV log, guessed from its first lines.

A log saved by a spreadsheet in a comma-decimal locale (German, French, ...) separates
columns with ``;`` and writes ``0,5`` for 0.5; a tab-separated export exists too. The
header line decides the separator (the most frequent of ``,`` ``;`` tab, commas winning
a tie), and a comma between digits in the data decides the decimal mark when the
separator is not a comma.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Dialect", "sniff"]

_DECIMAL_COMMA = re.compile(r"\d,\d")
_HEAD_BYTES = 64 * 1024  # enough for the header and a few data rows


@dataclass(frozen=True)
class Dialect:
    sep: str = ","
    decimal: str = "."

    @property
    def plain(self) -> bool:
        """Comma-separated with decimal points: what every reader assumes."""
        return self.sep == "," and self.decimal == "."

    def describe(self) -> str:
        """``';'-separated, decimal comma`` for messages and run metadata."""
        name = {"\t": "tab", ",": "','", ";": "';'"}[self.sep]
        mark = "comma" if self.decimal == "," else "point"
        return f"{name}-separated, decimal {mark}"


def sniff(path: Path, skiprows: int = 0) -> Dialect:
    """The dialect of ``path`` (after ``skiprows`` lines); unreadable bytes count as text."""
    with open(path, "rb") as f:
        head = f.read(_HEAD_BYTES).decode("utf-8-sig", errors="replace")
    lines = [ln for ln in head.splitlines()[skiprows:skiprows + 21] if ln.strip()]
    if not lines:
        return Dialect()
    header = lines[0]
    counts = {sep: header.count(sep) for sep in (",", ";", "\t")}
    sep = max(counts, key=lambda s: (counts[s], s == ","))
    if counts[sep] == 0 or sep == ",":
        return Dialect()
    data = lines[1:]
    decimal = "," if any(_DECIMAL_COMMA.search(ln) for ln in data) else "."
    return Dialect(sep, decimal)
