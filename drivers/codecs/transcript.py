"""Byte transcripts as files: raw binary captures or commented hex dumps.

A hex dump (``.hex``) holds hex byte pairs separated by white space; ``#`` starts a
comment to the end of the line. It is how the fixtures in ``fixtures/transcripts`` are
written, so they can be read (and checked against protocols.md) by eye.
"""

from __future__ import annotations

import re
from pathlib import Path

from drivers.errors import DeviceError

_PAIR = re.compile(r"^[0-9A-Fa-f]{2}$")


class TranscriptError(DeviceError):
    """A transcript file cannot be read; names the file and line."""


def parse_hex_dump(text: str, source: str = "<hex>") -> bytes:
    out = bytearray()
    for lineno, line in enumerate(text.splitlines(), start=1):
        for token in line.split("#", 1)[0].split():
            if not _PAIR.match(token):
                raise TranscriptError(f"{source}:{lineno}: {token!r} is not a hex byte "
                                      "(expected pairs like '24 4D 3C')")
            out.append(int(token, 16))
    return bytes(out)


def format_hex_dump(data: bytes, per_line: int = 16) -> str:
    return "".join(data[k : k + per_line].hex(" ").upper() + "\n"
                   for k in range(0, len(data), per_line))


def read_bytes(path: Path) -> bytes:
    """Bytes of a capture: ``.hex`` files are parsed as hex dumps, others read as is."""
    try:
        if path.suffix.lower() == ".hex":
            return parse_hex_dump(path.read_text(encoding="utf-8"), str(path))
        return path.read_bytes()
    except (OSError, UnicodeDecodeError) as exc:
        raise TranscriptError(f"{path}: cannot read ({exc.__class__.__name__}: "
                              f"{getattr(exc, 'strerror', None) or exc})") from None
