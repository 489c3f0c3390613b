"""Flight logs in: Betaflight/INAV blackbox, PX4 ULog, ArduPilot DataFlash.

Each reader returns ``FlightLog`` objects (run columns in SI units, plus metadata);
``rotorbench import`` writes each as a run of kind ``flight``. The format is read from
the file's first bytes (``detect_flight_format``), as the bench-log importers read a
header. Readers never need a device: they work on any log (docs/flight-logs.md).
"""

from __future__ import annotations

from pathlib import Path

from analysis.errors import LogError
from analysis.flightlogs.flight_log import FlightLog

__all__ = ["FLIGHT_FORMATS", "FlightLog", "detect_flight_format", "read_flight_log"]

FLIGHT_FORMATS = ("blackbox", "ulog", "dataflash")
_SNIFF_BYTES = 1 << 16


def detect_flight_format(path: str | Path) -> str | None:
    """``blackbox``, ``ulog`` or ``dataflash`` from the first bytes, else None."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(_SNIFF_BYTES)
    except OSError as exc:
        raise LogError(f"{path}: cannot read ({exc.strerror or exc})") from None
    # the readers' own constants, imported here so the CLI's start does not load readers
    from analysis.flightlogs.blackbox import MARKER
    from analysis.flightlogs.dataflash import FMT_TYPE, HEAD
    from analysis.flightlogs.ulog import MAGIC

    if head.startswith(MAGIC):
        return "ulog"
    if head.startswith(HEAD + bytes([FMT_TYPE])):  # a DataFlash log opens with the FMT of FMT
        return "dataflash"
    if MARKER in head:
        return "blackbox"
    return None


def read_flight_log(path: str | Path, fmt: str, *, max_rows: int | None = None
                    ) -> list[FlightLog]:
    """Every log in the file (a blackbox file may hold several), in file order."""
    path = Path(path)
    if not path.is_file():
        raise LogError(f"{path}: no such file")
    if fmt == "ulog":
        from analysis.flightlogs.ulog import read_ulog

        log = read_ulog(path)
        if max_rows is not None:
            log.keep_first(max_rows)
        return [log]
    if fmt == "blackbox":
        from analysis.flightlogs.blackbox import read_blackbox

        return read_blackbox(path, max_rows=max_rows)
    if fmt == "dataflash":
        from analysis.flightlogs.dataflash import read_dataflash

        return [read_dataflash(path, max_rows=max_rows)]
    raise LogError(f"--format {fmt!r}: expected one of {', '.join(FLIGHT_FORMATS)}")
