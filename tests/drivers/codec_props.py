"""Shared checks of the codec fuzz tests (loaded by file path: tests use importlib mode).

The central property: a byte-stream decoder fed frames mixed with damage must
* never raise, whatever the bytes and however they are chunked;
* account for every byte: ``bytes_in == frame_bytes + garbage_bytes + buffered``;
* give the same messages for any chunking of the same stream;
* recover every intact frame, except frames overlapped by a *spurious* frame that the
  damaged bytes happened to form with a valid checksum (which no checksum can prevent;
  the test then knows exactly which frames may be lost).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from hypothesis import strategies as st

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures" / "transcripts"


@dataclass(frozen=True)
class Piece:
    """A piece of a test stream: an intact frame (with its message) or damage."""

    data: bytes
    message: object = None
    intact: bool = False


def assemble(pieces: Sequence[Piece]) -> tuple[bytes, list[tuple[int, int, object]]]:
    """Stream bytes and the (offset, length, message) of every intact frame."""
    out, frames, pos = bytearray(), [], 0
    for p in pieces:
        if p.intact:
            frames.append((pos, len(p.data), p.message))
        out += p.data
        pos += len(p.data)
    return bytes(out), frames


def feed_chunked(decoder, data: bytes, cuts: Sequence[int]) -> list:
    """Feed ``data`` split at ``cuts`` (sorted positions), then flush; located messages."""
    located, last = [], 0
    for c in [*sorted(set(cuts)), len(data)]:
        c = min(max(c, last), len(data))
        located += decoder.feed_located(data[last:c])
        last = c
    located += decoder.flush_located()
    return located


def check_stream(make_decoder: Callable[[], object], data: bytes,
                 frames: list[tuple[int, int, object]], cuts: Sequence[int]
                 ) -> tuple[object, list]:
    """Run the central property (see module docstring); returns (decoder, located)."""
    whole = make_decoder()
    located_whole = feed_chunked(whole, data, [])
    dec = make_decoder()
    located = feed_chunked(dec, data, cuts)
    assert [(x.offset, x.message) for x in located] == \
        [(x.offset, x.message) for x in located_whole], "chunking changed the result"
    s = dec.stats
    assert dec.buffered == 0
    assert s.bytes_in == len(data) == s.frame_bytes + s.garbage_bytes
    assert s.messages == len(located)
    got = [(x.offset, x.message) for x in located]
    expected = [(off, msg) for off, _, msg in frames]
    spurious = [(x.offset, x.length) for x in located
                if (x.offset, x.message) not in expected]
    for off, length, msg in frames:
        overlapped = any(o < off + length and off < o + n for o, n in spurious)
        if not overlapped:
            assert (off, msg) in got, f"intact frame at {off} lost: {msg!r}"
    return dec, located


def damage(frame: bytes, data: st.DataObject) -> Piece:
    """One way a link damages a frame: cut it short, flip a byte, or drop a byte."""
    kind = data.draw(st.sampled_from(["cut", "flip", "drop"]))
    if kind == "cut" or len(frame) < 2:
        return Piece(frame[: data.draw(st.integers(1, max(1, len(frame) - 1)))])
    k = data.draw(st.integers(0, len(frame) - 1))
    if kind == "flip":
        mask = data.draw(st.integers(1, 255))
        return Piece(frame[:k] + bytes([frame[k] ^ mask]) + frame[k + 1 :])
    return Piece(frame[:k] + frame[k + 1 :])


@st.composite
def streams(draw: st.DrawFn, frames: st.SearchStrategy, garbage: st.SearchStrategy | None = None,
            damaged: bool = True, max_frames: int = 8, damage_one_in: int = 5,
            trailing: bool = False) -> tuple[bytes, list, list[int]]:
    """A test stream of ``(frame bytes, message)`` draws with garbage between them, some
    frames damaged (one in ``damage_one_in``), optional trailing garbage, and chunk cuts."""
    garbage = st.binary(max_size=12) if garbage is None else garbage
    pieces = []
    for frame, msg in draw(st.lists(frames, min_size=1, max_size=max_frames)):
        if draw(st.booleans()):
            pieces.append(Piece(draw(garbage)))
        if damaged and draw(st.integers(0, damage_one_in - 1)) == 0:
            pieces.append(damage(frame, draw(st.data())))
        else:
            pieces.append(Piece(frame, msg, intact=True))
    if trailing and draw(st.booleans()):
        pieces.append(Piece(draw(garbage)))
    data, intact = assemble(pieces)
    return data, intact, draw(st.lists(st.integers(0, len(data)), max_size=6))
