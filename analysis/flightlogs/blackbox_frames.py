"""Delimit blackbox frames with one regular expression, so Python never walks bytes.

A frame has no length field: its length follows from the field encodings. Every
encoding's byte shape is a regular language (a variable-byte value is
``[\\x80-\\xff]{0,4}[\\x00-\\x7f]``; a tag byte's value fixes how many bytes follow), so
a frame type is a regular expression, and the whole stream is a ``findall`` of "a frame
that is followed by a frame marker (or the end), else one garbage run". The C regex
engine walks the bytes; Python only sees one string per frame. A frame that does not
decode, or is not followed by a marker, falls to the garbage branch, which is how the
format documents recovery (resynchronise at the next byte).
"""

from __future__ import annotations

import re

from analysis.flightlogs.blackbox_encodings import (
    GROUP_SIZE,
    NEG_14BIT,
    NULL,
    SIGNED_VB,
    TAG2_3S32,
    TAG2_3SVARIABLE,
    TAG8_4S16,
    TAG8_8SVB,
    UNSIGNED_VB,
)

__all__ = [
    "EVENTS",
    "EVENT_LOG_END",
    "UnsupportedEncodingError",
    "frame_regex",
    "groups",
]

VB = rb"[\x80-\xff]{0,4}[\x00-\x7f]"
EVENTS = {0: "SYNC_BEEP", 13: "INFLIGHT_ADJUSTMENT", 14: "LOGGING_RESUME", 15: "DISARM",
          30: "FLIGHTMODE", 255: "LOG_END"}
EVENT_LOG_END = b"E\xffEnd of log\x00"


class UnsupportedEncodingError(ValueError):
    """A field encoding this decoder does not read (Elias delta, ...)."""


def groups(encodings: list[int]) -> list[tuple[int, list[int]]]:
    """The fields in the order they are written, as (encoding, field indices) groups:
    tag2_3s32 / tag2_3svariable take 3 fields, tag8_4s16 4, a tag8_8svb run up to 8."""
    out: list[tuple[int, list[int]]] = []
    i, n = 0, len(encodings)
    while i < n:
        enc = encodings[i]
        if enc in GROUP_SIZE:
            size = GROUP_SIZE[enc]
        elif enc == TAG8_8SVB:
            size = 1
            while i + size < n and size < 8 and encodings[i + size] == TAG8_8SVB:
                size += 1
        else:
            size = 1
        out.append((enc, list(range(i, min(i + size, n)))))
        i += size
    return out


def _cls(values: list[int]) -> bytes:
    return b"[" + b"".join(re.escape(bytes([v])) for v in values) + b"]"


def _by_length(lengths: dict[int, int]) -> bytes:
    """An alternation over lead bytes, each followed by its number of further bytes."""
    by: dict[int, list[int]] = {}
    for lead, extra in lengths.items():
        by.setdefault(extra, []).append(lead)
    return b"(?:" + b"|".join(_cls(leads) + (b".{%d}" % extra if extra else b"")
                              for extra, leads in sorted(by.items())) + b")"


def _tag2_lengths() -> dict[int, int]:
    out = {}
    for lead in range(256):
        sel = lead >> 6
        out[lead] = sel if sel < 3 else sum(((lead >> (2 * k)) & 3) + 1 for k in range(3))
    return out


def _tag8_4s16_lengths() -> dict[int, int]:
    nib = (0, 1, 2, 4)
    return {s: (sum(nib[(s >> (2 * k)) & 3] for k in range(4)) + 1) // 2 for s in range(256)}


def _group_regex(enc: int, n: int) -> bytes:
    if enc in (SIGNED_VB, UNSIGNED_VB, NEG_14BIT):
        return VB
    if enc == NULL:
        return b""
    if enc in (TAG2_3S32, TAG2_3SVARIABLE):
        return _by_length(_tag2_lengths())
    if enc == TAG8_4S16:
        return _by_length(_tag8_4s16_lengths())
    if enc == TAG8_8SVB:
        if n == 1:
            return VB
        by: dict[int, list[int]] = {}
        for head in range(1 << n):
            by.setdefault(head.bit_count(), []).append(head)
        return b"(?:" + b"|".join(_cls(h) + (b"(?:" + VB + b"){%d}" % k if k else b"")
                                  for k, h in sorted(by.items())) + b")"
    raise UnsupportedEncodingError(enc)


def frame_body(encodings: list[int]) -> bytes:
    return b"".join(_group_regex(enc, len(idx)) for enc, idx in groups(encodings))


def frame_regex(bodies: dict[bytes, bytes]) -> re.Pattern[bytes]:
    """``bodies``: marker letter -> field regex. Matches one frame (followed by a marker
    or the end), one known event, or else a run of garbage (one marker letter, or the
    bytes up to the next one)."""
    markers = b"".join(sorted({*bodies, b"E"}))
    ahead = b"(?=[" + markers + rb"]|\Z)"
    events = (rb"E(?:\x00" + VB + rb"|\x0e" + VB + VB + rb"|\x0f" + VB + rb"|\x1e" + VB + VB
              + rb"|\x0d(?:[\x00-\x7f]" + VB + rb"|[\x80-\xff]....))" + ahead
              + b"|" + re.escape(EVENT_LOG_END))
    frames = b"|".join(re.escape(m) + body + ahead for m, body in bodies.items())
    garbage = b"[^" + markers + b"]+|."
    return re.compile(b"(?:" + frames + b"|" + events + b"|" + garbage + b")", re.DOTALL)
