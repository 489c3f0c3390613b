"""The load cell's mechanics as a digital filter: a 2nd-order low-pass run block by block.

The cell + motor mount is a mass-spring-damper, ``omega_n^2 / (s^2 + 2 zeta omega_n s +
omega_n^2)``, discretised with the bilinear transform at the DAQ's sample rate. This used
to be ``scipy.signal.bilinear`` + ``lfilter``; importing ``scipy.signal`` took longer than
a 20-repeat simulated step run, so the same filter is written here in numpy alone.

The recursion is split into two first-order ones over the poles (partial fractions), each
solved for a whole chunk at once with a cumulative sum: ``w[n] = p w[n-1] + r x[n]`` is
``w[n] = p^(n+1) (w[-1] + r sum_{m<=n} p^-(m+1) x[m])``. Chunks are short enough that
``|p|^-L`` stays below 1e3 (124 for the shipped 150 Hz cell at 25 kHz), so the output
matches ``lfilter`` to about 1e-13 relative, whatever the block slicing. Complex poles
(an underdamped cell) come in a conjugate pair whose parts are conjugate too: one is
computed and its real part doubled. No Python loop runs per sample.
"""

from __future__ import annotations

import math
from typing import TypeAlias

import numpy as np

#: One first-order part's state: ``w`` before the chunk, samples done in it, running sum.
PartSnapshot: TypeAlias = tuple[tuple[float, float], int, tuple[float, float]]

__all__ = ["SecondOrderLowPass", "bilinear_low_pass"]

_MAX_CHUNK = 512  # samples solved at once: one 20 ms tick at 25 kHz
_MAX_GROWTH = 1e3  # |p|^-L at most: the cumulative sum keeps ~13 significant digits


def bilinear_low_pass(fn_hz: float, zeta: float, fs_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """``(b, a)`` of ``omega_n^2 / (s^2 + 2 zeta omega_n s + omega_n^2)`` by the bilinear
    transform ``s = 2 fs (z - 1) / (z + 1)`` (the coefficients of ``scipy.signal.bilinear``)."""
    wn = 2.0 * math.pi * fn_hz
    k = 2.0 * fs_hz
    w2, d1 = wn * wn, 2.0 * zeta * wn
    a0 = k * k + d1 * k + w2
    b = np.array([w2, 2.0 * w2, w2]) / a0
    a = np.array([a0, 2.0 * w2 - 2.0 * k * k, k * k - d1 * k + w2]) / a0
    return b, a


class _FirstOrder:
    """``w[n] = p w[n-1] + r x[n]`` over whole chunks (cumulative sums), state carried.

    Within a chunk that starts with state ``s``: ``w[n] = p^(n+1) (s + r S[n])`` with the
    running sum ``S[n] = sum_{m<=n} p^-(m+1) x[m]``. Only ``Re(w)`` is needed per sample:
    ``S_r A - S_i B + (s_r g_r - s_i g_i)`` with ``g = p^(n+1)``, ``A + iB = r g``.

    Chunks sit on a fixed grid of sample indices and a chunk split between two calls
    carries its running sum, so every output is computed by the same operations whatever
    the block slicing: reading 1 s at once gives bit for bit the samples of 50 reads. The
    complex products are spelled out in real arithmetic because numpy's complex multiply
    rounds differently in its vectorised and scalar loops (so by position in the array).
    """

    def __init__(self, pole: complex, residue: complex, chunk: int) -> None:
        self.chunk = chunk
        grow = pole ** np.arange(1, chunk + 1)  # p^(n+1), n = 0..L-1
        shrink = 1.0 / grow
        self._gr, self._gi = grow.real.copy(), grow.imag.copy()
        self._sr, self._si = shrink.real.copy(), shrink.imag.copy()
        rg = residue * grow
        self._a, self._b = rg.real.copy(), rg.imag.copy()
        self._end = (float(self._a[-1]), float(self._b[-1]), float(self._gr[-1]),
                     float(self._gi[-1]))
        self.state = (0.0, 0.0)  # w just before the current chunk
        self.offset = 0  # samples of the current chunk already done
        self.running = (0.0, 0.0)  # the running sum so far in the current chunk

    def real(self, x: np.ndarray) -> np.ndarray:
        """``Re(w)`` for the next block ``x`` (real)."""
        n = x.size
        out = np.empty(n)
        start = 0
        if self.offset:  # finish the chunk a previous block began
            start = self._piece(x, 0, min(self.chunk - self.offset, n), out)
        whole = (n - start) // self.chunk
        if whole:
            start = self._whole(x, start, whole, out)
        if start < n:
            self._piece(x, start, n - start, out)
        return out

    def _next_state(self, s_r: float, s_i: float, e_r: float, e_i: float) -> tuple[float, float]:
        """``w`` at a chunk's last sample: the state the next chunk starts from."""
        a, b, gr, gi = self._end
        # (s + r S) g with r g = a + ib: real and imaginary parts, in a fixed order
        return (e_r * a - e_i * b + (s_r * gr - s_i * gi),
                e_r * b + e_i * a + (s_r * gi + s_i * gr))

    def _piece(self, x: np.ndarray, start: int, m: int, out: np.ndarray) -> int:
        """Samples ``start .. start + m`` of ``x``, within one chunk of the grid."""
        o = self.offset
        sl = slice(o, o + m)
        seg = x[start:start + m]
        sum_r, sum_i = seg * self._sr[sl], seg * self._si[sl]
        sum_r[0] += self.running[0]  # continue the chunk's sum where it stopped
        sum_i[0] += self.running[1]
        np.cumsum(sum_r, out=sum_r)
        np.cumsum(sum_i, out=sum_i)
        self.running = (float(sum_r[-1]), float(sum_i[-1]))
        s_r, s_i = self.state
        free = self._gr[sl] * s_r
        free -= self._gi[sl] * s_i
        self._real_part(sum_r, sum_i, free, self._a[sl], self._b[sl], out[start:start + m])
        self.offset = o + m
        if self.offset == self.chunk:
            self.state = self._next_state(s_r, s_i, *self.running)
            self.offset, self.running = 0, (0.0, 0.0)
        return start + m

    def _whole(self, x: np.ndarray, start: int, count: int, out: np.ndarray) -> int:
        """``count`` whole chunks from ``start`` at once: the same operations per sample
        as ``_piece``, with only the chunk-to-chunk state carried in a scalar loop."""
        L = self.chunk
        stop = start + count * L
        seg = x[start:stop].reshape(count, L)
        sum_r = seg * self._sr
        sum_i = seg * self._si
        np.cumsum(sum_r, axis=1, out=sum_r)
        np.cumsum(sum_i, axis=1, out=sum_i)
        st_r, st_i = np.empty((count, 1)), np.empty((count, 1))
        state = self.state
        for c, (e_r, e_i) in enumerate(zip(sum_r[:, -1].tolist(), sum_i[:, -1].tolist(),
                                           strict=True)):
            st_r[c, 0], st_i[c, 0] = state
            state = self._next_state(state[0], state[1], e_r, e_i)
        self.state = state
        free = st_r * self._gr
        free -= st_i * self._gi
        self._real_part(sum_r, sum_i, free, self._a, self._b, out[start:stop].reshape(count, L))
        return stop

    @staticmethod
    def _real_part(sum_r: np.ndarray, sum_i: np.ndarray, free: np.ndarray, a: np.ndarray,
                   b: np.ndarray, out: np.ndarray) -> None:
        """``out = (S_r a - S_i b) + free`` (the running sums are overwritten)."""
        sum_r *= a
        sum_i *= b
        np.subtract(sum_r, sum_i, out=out)
        out += free

    def snapshot(self) -> PartSnapshot:
        return self.state, self.offset, self.running

    def restore(self, snap: PartSnapshot) -> None:
        self.state, self.offset, self.running = snap


class SecondOrderLowPass:
    """``y = lfilter(b, a, x)`` for a 2nd-order section, with its state carried between
    calls (so slicing the input into blocks does not change the output).

    The sum of two first-order parts (partial fractions; one part when the poles are a
    conjugate pair, the underdamped cell). A double pole (``zeta`` = 1 exactly) has no
    such split: its poles are moved apart by 1e-6 relative, which changes the response by
    about that much and keeps it within ~1e-7 of ``lfilter``.
    """

    def __init__(self, b: np.ndarray, a: np.ndarray) -> None:
        b = np.asarray(b, float) / a[0]
        a = np.asarray(a, float) / a[0]
        p1, p2 = (complex(p) for p in np.roots(a))
        if abs(p1 - p2) < 1e-6 * abs(p1):
            p1, p2 = p1 * (1.0 + 5e-7), p2 * (1.0 - 5e-7)
        decay = -math.log(min(abs(p1), abs(p2), 1.0 - 1e-12))
        chunk = int(max(8, min(_MAX_CHUNK, math.log(_MAX_GROWTH) / decay)))
        direct = b[2] / a[2]  # the filter's direct term (numerator degree = 2)
        c0, c1 = b[0] - direct, b[1] - direct * a[1]
        self._direct = direct
        conjugate = p1.imag != 0.0
        parts = [(p1, (c0 + c1 / p1) / (1.0 - p2 / p1))]
        if not conjugate:
            parts.append((p2, (c0 + c1 / p2) / (1.0 - p1 / p2)))
        self._parts = tuple(_FirstOrder(p, r, chunk) for p, r in parts)
        self._weight = 2.0 if conjugate else 1.0  # w2 = conj(w1): y gets 2 Re(w1)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Filter the next block of samples."""
        x = np.asarray(x, float)
        y = x * self._direct
        if x.size == 0:
            return y
        for part in self._parts:
            w = part.real(x)
            w *= self._weight
            y += w
        return y

    def snapshot(self) -> tuple[PartSnapshot, ...]:
        """The filter's state, for ``restore`` (a simulated rig's checkpoint)."""
        return tuple(part.snapshot() for part in self._parts)

    def restore(self, snap: tuple[PartSnapshot, ...]) -> None:
        for part, state in zip(self._parts, snap, strict=True):
            part.restore(state)
