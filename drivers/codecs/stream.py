"""The common incremental decoder shape every byte-stream codec fills.

A serial port or TCP socket hands out bytes in arbitrary chunks. A ``FrameDecoder`` takes
them with ``feed(data)`` and returns every complete message found so far; ``flush()`` ends
the stream (a capture file, a closed port). It never blocks and never raises on bad
input: bytes that cannot start a frame are skipped as garbage, frames whose checksum
fails are dropped, and the decoder resynchronises on the next possible frame start. What
was dropped is counted in ``stats`` so a driver (or ``rotorbench decode``) can tell a
clean link from a noisy one.

Counting rules (the same for every codec):

* ``garbage_bytes``: bytes that did not end up in a decoded message.
* ``bad_checksums``: complete candidate frames whose checksum/CRC failed (candidates that
  start inside a frame already counted as failed are resync attempts, not counted again).
* ``truncated``: frames cut short, seen either at ``flush()`` (a frame whose header was
  complete but whose body never arrived) or as a failed frame inside which a valid frame
  starts (the usual signature of a dropout: the next frame overwrote the tail).
* ``malformed``: frames with a valid checksum whose content does not fit the message
  layout (e.g. a payload of the wrong length for its command).
* ``resyncs``: times a message was decoded right after skipped bytes.

Invariant: ``bytes_in == frame_bytes + garbage_bytes + buffered``.
"""

from __future__ import annotations

import enum
import re
from abc import ABC, abstractmethod
from dataclasses import asdict, dataclass
from typing import Generic, TypeVar

M = TypeVar("M")

#: Decoder counters that mean data was lost on the link (every codec's stats use these
#: names; CAN decoders: ``bad_crc``, ``orphan_frames``; DroneCAN telemetry adds the
#: transfers missing from its transfer-id sequence). Garbage bytes and resyncs are not
#: losses on their own: a link that drops a frame also shows up in these.
LOSS_COUNTERS = ("bad_checksums", "bad_crc", "truncated", "malformed", "orphan_frames",
                 "transfer_id_gaps")


def link_losses(stats: object) -> dict[str, int]:
    """The non-zero loss counters of a decoder's ``stats`` (``run.json``: ``link_errors``)."""
    out = {k: int(getattr(stats, k)) for k in LOSS_COUNTERS if getattr(stats, k, 0)}
    return out


@dataclass
class DecoderStats:
    """Counters of one decoder; see the module docstring for the rules."""

    bytes_in: int = 0
    messages: int = 0
    frame_bytes: int = 0
    garbage_bytes: int = 0
    bad_checksums: int = 0
    truncated: int = 0
    malformed: int = 0
    resyncs: int = 0

    def as_dict(self) -> dict[str, int]:
        return asdict(self)


class Status(enum.Enum):
    """What a codec's ``try_frame`` found at a candidate frame start."""

    OK = "ok"  # a complete, valid frame: (length, message)
    NOT_A_FRAME = "not_a_frame"  # the header is impossible: skip one byte
    NEED_HEADER = "need_header"  # too few bytes to judge the header yet
    NEED_BODY = "need_body"  # header valid, body still arriving
    BAD_CHECKSUM = "bad_checksum"  # complete frame, checksum failed: (length, None)
    MALFORMED = "malformed"  # checksum fine, content impossible: (length, None)


@dataclass(frozen=True)
class Attempt(Generic[M]):
    """Result of ``try_frame``: a status, the frame length when known, the message if OK."""

    status: Status
    length: int = 0
    message: M | None = None


NEED_HEADER: Attempt = Attempt(Status.NEED_HEADER)
NEED_BODY: Attempt = Attempt(Status.NEED_BODY)
NOT_A_FRAME: Attempt = Attempt(Status.NOT_A_FRAME)


@dataclass(frozen=True)
class Located(Generic[M]):
    """A decoded message, the absolute offset of its first byte and its length in bytes."""

    offset: int
    message: M
    length: int = 0


class FrameDecoder(ABC, Generic[M]):
    """Incremental resynchronising decoder; subclasses say where frames may start and
    how to parse one.

    ``sync`` is a compiled regex that matches one possible first byte of a frame.
    """

    sync: re.Pattern[bytes]

    def __init__(self) -> None:
        self._buf = bytearray()
        self._base = 0  # absolute stream offset of self._buf[0]
        self._fail_end = -1  # absolute end of the last frame that failed its checksum
        self._skipped = False
        self.stats = DecoderStats()

    @abstractmethod
    def try_frame(self, buf: bytes | bytearray, start: int, /) -> Attempt[M]:
        """Judge the candidate frame starting at ``buf[start]`` (never raises)."""

    def feed(self, data: bytes | bytearray) -> list[M]:
        """Add bytes; return the messages completed by them (possibly none)."""
        return [loc.message for loc in self.feed_located(data)]

    def flush(self) -> list[M]:
        """End of stream: decode what is left, count a partial frame as truncated."""
        return [loc.message for loc in self.flush_located()]

    def feed_located(self, data: bytes | bytearray) -> list[Located[M]]:
        """Like ``feed`` but each message comes with its byte offset in the stream."""
        self._buf += data
        self.stats.bytes_in += len(data)
        return self._drain(final=False)

    def flush_located(self) -> list[Located[M]]:
        return self._drain(final=True)

    @property
    def buffered(self) -> int:
        """Bytes held back waiting for the rest of a frame."""
        return len(self._buf)

    def _skip(self, n: int) -> None:
        if n > 0:
            self.stats.garbage_bytes += n
            self._skipped = True

    def _drain(self, *, final: bool) -> list[Located[M]]:
        buf, out, i, n = self._buf, [], 0, len(self._buf)
        while i < n:
            hit = self.sync.search(buf, i)
            if hit is None:
                self._skip(n - i)
                i = n
                break
            j = hit.start()
            self._skip(j - i)
            i = j
            att = self.try_frame(buf, i)
            st = att.status
            if st is Status.OK:
                start_abs = self._base + i
                if start_abs < self._fail_end:
                    # The failed frame was cut short by this one (see module docstring).
                    self.stats.bad_checksums -= 1
                    self.stats.truncated += 1
                self._fail_end = -1
                if self._skipped:
                    self.stats.resyncs += 1
                    self._skipped = False
                self.stats.messages += 1
                self.stats.frame_bytes += att.length
                out.append(Located(start_abs, att.message, att.length))
                i += att.length
                continue
            if st in (Status.NEED_HEADER, Status.NEED_BODY):
                if not final:
                    break
                if st is Status.NEED_BODY:
                    self.stats.truncated += 1
                self._skip(1)
                i += 1
                continue
            if st is Status.BAD_CHECKSUM and self._base + i >= self._fail_end:
                # Candidates found while resynchronising inside a frame that already
                # failed are not counted again (stray sync bytes in its payload).
                self.stats.bad_checksums += 1
                self._fail_end = self._base + i + att.length
            elif st is Status.MALFORMED:
                self.stats.malformed += 1
            self._skip(1)
            i += 1
        del buf[:i]
        self._base += i
        return out


def hex_bytes(data: bytes) -> str:
    """Space-separated upper-case hex, the notation of protocols.md and the transcripts."""
    return data.hex(" ").upper()
