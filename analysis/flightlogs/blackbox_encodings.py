"""Blackbox field encodings, decoded for many frames at once.

Written from the format's documentation (Betaflight's "Blackbox logging internals" and
the encoder's behaviour), not from any GPL decoder. Every function takes the data as a
uint8 array ``buf`` (padded with at least 16 zero bytes past the end) and ``pos``, one
byte offset per frame, and returns the decoded values (int64, one row per frame) and the
offsets after them: the frames were already delimited (``blackbox_frames``), so each
field is one vectorised step across all frames instead of a Python loop per frame.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "ENCODING_NAMES",
    "GROUP_SIZE",
    "NEG_14BIT",
    "NULL",
    "SIGNED_VB",
    "TAG2_3S32",
    "TAG2_3SVARIABLE",
    "TAG8_4S16",
    "TAG8_8SVB",
    "UNSIGNED_VB",
    "decode_group",
]

SIGNED_VB, UNSIGNED_VB, NEG_14BIT = 0, 1, 3
TAG8_8SVB, TAG2_3S32, TAG8_4S16, NULL, TAG2_3SVARIABLE = 6, 7, 8, 9, 10
ENCODING_NAMES = {0: "signed VB", 1: "unsigned VB", 3: "neg 14-bit", 4: "Elias delta u32",
                  5: "Elias delta s32", 6: "tag8_8svb", 7: "tag2_3s32", 8: "tag8_4s16",
                  9: "null", 10: "tag2_3svariable"}
GROUP_SIZE = {TAG2_3S32: 3, TAG8_4S16: 4, TAG2_3SVARIABLE: 3}  # fields per group


def _sext(v: np.ndarray, bits: np.ndarray | int) -> np.ndarray:
    """Sign-extend the low ``bits`` bits of ``v``."""
    bits = np.asarray(bits, dtype=np.int64)
    sign = np.left_shift(np.int64(1), bits - 1)
    mask = np.left_shift(np.int64(1), bits) - 1
    v = v & mask
    return (v ^ sign) - sign


def uvb(buf: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unsigned variable bytes: 7 bits a byte, low group first, bit 7 = more (<= 5)."""
    b = buf[pos].astype(np.int64)
    val = b & 0x7F
    more = b >= 0x80
    n = np.ones_like(pos)
    for k in range(1, 5):
        if not more.any():
            break
        b = buf[pos + k].astype(np.int64)
        val = np.where(more, val | ((b & 0x7F) << (7 * k)), val)
        n += more
        more &= b >= 0x80
    return val & 0xFFFFFFFF, pos + n


def zigzag(u: np.ndarray) -> np.ndarray:
    return (u >> 1) ^ -(u & 1)


def svb(buf: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    u, pos = uvb(buf, pos)
    return zigzag(u), pos


def neg14(buf: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    u, pos = uvb(buf, pos)
    return -_sext(u, 14), pos


def tag8_8svb(buf: np.ndarray, pos: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` fields: one signed VB if n == 1, else a header byte (bit k: field k follows)."""
    out = np.zeros((len(pos), n), np.int64)
    if n == 1:
        out[:, 0], pos = svb(buf, pos)
        return out, pos
    head = buf[pos].astype(np.int64)
    pos = pos + 1
    for k in range(n):
        has = (head >> k) & 1 == 1
        if has.any():
            v, after = svb(buf, pos)
            out[:, k] = np.where(has, v, 0)
            pos = np.where(has, after, pos)
    return out, pos


def _le(buf: np.ndarray, pos: np.ndarray, nbytes: np.ndarray) -> np.ndarray:
    """Little-endian signed values of 1..4 bytes each."""
    v = np.zeros(len(pos), np.int64)
    for k in range(4):
        v |= np.where(nbytes > k, buf[pos + k].astype(np.int64) << (8 * k), 0)
    return _sext(v, 8 * nbytes)


def tag2_3s32(buf: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """3 fields: 2-bit, 4-bit or 6-bit packed, or byte counts (selector = top 2 bits)."""
    b0 = buf[pos].astype(np.int64)
    b1 = buf[pos + 1].astype(np.int64)
    b2 = buf[pos + 2].astype(np.int64)
    sel = b0 >> 6
    out = np.zeros((len(pos), 3), np.int64)
    s0 = sel == 0
    out[s0] = np.stack([_sext(b0 >> 4, 2), _sext(b0 >> 2, 2), _sext(b0, 2)], 1)[s0]
    s1 = sel == 1
    out[s1] = np.stack([_sext(b0, 4), _sext(b1 >> 4, 4), _sext(b1, 4)], 1)[s1]
    s2 = sel == 2
    out[s2] = np.stack([_sext(b0, 6), _sext(b1, 6), _sext(b2, 6)], 1)[s2]
    end = pos + 1 + sel  # selectors 0, 1, 2: 1, 2, 3 bytes
    s3 = sel == 3
    if s3.any():
        p = pos[s3] + 1
        lead = b0[s3]
        for k in range(3):
            nb = ((lead >> (2 * k)) & 3) + 1
            out[s3, k] = _le(buf, p, nb)
            p = p + nb
        end[s3] = p
    return out, end


def tag2_3svariable(buf: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """3 fields: 2/2/2, 5/5/4 or 8/7/7 bits, or byte counts (selector = top 2 bits)."""
    b0 = buf[pos].astype(np.int64)
    b1 = buf[pos + 1].astype(np.int64)
    b2 = buf[pos + 2].astype(np.int64)
    out, end = tag2_3s32(buf, pos)  # selectors 0 and 3 are laid out as tag2_3s32
    sel = b0 >> 6
    s1 = sel == 1
    out[s1] = np.stack([_sext(b0 >> 1, 5), _sext(((b0 & 1) << 4) | (b1 >> 4), 5),
                        _sext(b1, 4)], 1)[s1]
    s2 = sel == 2
    out[s2] = np.stack([_sext(((b0 & 0x3F) << 2) | (b1 >> 6), 8),
                        _sext(((b1 & 0x3F) << 1) | (b2 >> 7), 7), _sext(b2, 7)], 1)[s2]
    return out, end


_NIBBLES = np.array([0, 1, 2, 4])  # tag8_4s16 selector -> nibbles


def tag8_4s16(buf: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """4 fields (data version 2): a selector byte (2 bits a field: 0, 4, 8 or 16 bits),
    then the values as a nibble stream, high nibble first."""
    sel = buf[pos].astype(np.int64)
    byte = pos + 1
    half = np.zeros(len(pos), bool)  # the next nibble is the low one of buf[byte]
    out = np.zeros((len(pos), 4), np.int64)
    for k in range(4):
        nib = _NIBBLES[(sel >> (2 * k)) & 3]
        v = np.zeros(len(pos), np.int64)
        for j in range(4):
            take = nib > j
            if not take.any():
                break
            b = buf[byte].astype(np.int64)
            n = np.where(half, b & 0xF, b >> 4)
            v = np.where(take, (v << 4) | n, v)
            byte = np.where(take & half, byte + 1, byte)
            half = np.where(take, ~half, half)
        out[:, k] = np.where(nib > 0, _sext(v, np.maximum(nib * 4, 1)), 0)
    return out, byte + half


def decode_group(buf: np.ndarray, pos: np.ndarray, encoding: int, n: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Decode one group (``n`` fields of one encoding) for every frame: (values, pos)."""
    if encoding == SIGNED_VB:
        v, pos = svb(buf, pos)
    elif encoding == UNSIGNED_VB:
        v, pos = uvb(buf, pos)
    elif encoding == NEG_14BIT:
        v, pos = neg14(buf, pos)
    elif encoding == NULL:
        v = np.zeros(len(pos), np.int64)
    elif encoding == TAG8_8SVB:
        return tag8_8svb(buf, pos, n)
    elif encoding == TAG2_3S32:
        return tag2_3s32(buf, pos)
    elif encoding == TAG2_3SVARIABLE:
        return tag2_3svariable(buf, pos)
    elif encoding == TAG8_4S16:
        return tag8_4s16(buf, pos)
    else:
        raise ValueError(f"encoding {encoding}")
    return v[:, None], pos
