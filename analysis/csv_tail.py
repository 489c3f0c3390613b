"""The last line of a CSV log that was cut while being written or copied.

A logger stopped mid-write (power loss, a full disk, a copy interrupted) leaves a file
whose last line has no line break and, usually, fewer fields than the header: pandas
reads it as a row whose missing cells are empty and whose last cell is cut ('0.' for
'0.5904'). That row is not data; it is dropped and the import says so. A last line
without a line break but with every field is kept for a hand-written CSV (an editor may
omit the final break), and dropped for a logger's own format (``logger=True``: the
RCbenchmark and ESC32 programs end every line they write).
"""

from __future__ import annotations

import csv
import os
from pathlib import Path

__all__ = ["cut_last_line"]

#: how far back from the end the last line is looked for (a longer line is "cut" only
#: by the logger rule: its fields cannot be counted cheaply)
_TAIL_BYTES = 1 << 16


def cut_last_line(path: Path, n_fields: int, *, logger: bool) -> str | None:
    """The text of the file's last line if it is a partial row, else None.

    ``n_fields``: the header's field count; ``logger``: the file comes from a program
    that ends every line with a break, so a missing final break alone means a cut.
    """
    with Path(path).open("rb") as fh:
        size = fh.seek(0, os.SEEK_END)
        if size == 0:
            return None
        fh.seek(max(0, size - _TAIL_BYTES))
        tail = fh.read()
    if tail.endswith((b"\n", b"\r")):
        return None
    start = max(tail.rfind(b"\n"), tail.rfind(b"\r"))
    if start < 0 and size > len(tail):  # the last line is longer than the tail read
        return tail.decode("utf-8", errors="replace") if logger else None
    line = tail[start + 1:].decode("utf-8", errors="replace")
    try:
        fields = len(next(csv.reader([line], skipinitialspace=True), []))
    except csv.Error:  # an unclosed quote: cut inside a quoted cell
        return line
    return line if logger or fields < n_fields else None
