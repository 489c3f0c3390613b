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

import numpy as np

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
    """``w[n] = p w[n-1] + r x[n]`` over whole chunks (cumulative sums), state carried."""

    def __init__(self, pole: complex, residue: complex, chunk: int) -> None:
        self.pole, self.residue, self.chunk = pole, residue, chunk
        self._grow = pole ** np.arange(1, chunk + 1)  # p^(n+1), n = 0..L-1
        self._shrink = 1.0 / self._grow
        self.state = 0j  # w[-1]

    def __call__(self, x: np.ndarray) -> np.ndarray:
        out = np.empty(x.size, complex)
        for start in range(0, x.size, self.chunk):
            stop = min(start + self.chunk, x.size)
            m = stop - start
            acc = np.cumsum(x[start:stop] * self._shrink[:m])
            acc *= self.residue
            acc += self.state
            acc *= self._grow[:m]
            self.state = acc[-1]
            out[start:stop] = acc
        return out


class SecondOrderLowPass:
    """``y = lfilter(b, a, x)`` for a 2nd-order section, with its state carried between
    calls (so slicing the input into blocks does not change the output).

    Distinct poles: the sum of two first-order parts (partial fractions; one part when the
    poles are a conjugate pair). Nearly equal real poles (``zeta`` close to 1) make those
    parts cancel, so there the section runs as a cascade of two first-order stages, each
    after its numerator zero: ``u = (1 - z1 q) x / (1 - p1 q)``, ``y = b0 (1 - z2 q) u /
    (1 - p2 q)`` with ``q`` the one-sample delay.
    """

    def __init__(self, b: np.ndarray, a: np.ndarray) -> None:
        b = np.asarray(b, float) / a[0]
        a = np.asarray(a, float) / a[0]
        p1, p2 = np.roots(a).astype(complex)
        decay = -math.log(min(abs(p1), abs(p2), 1.0 - 1e-12))
        chunk = int(max(8, min(_MAX_CHUNK, math.log(_MAX_GROWTH) / decay)))
        self.cascade = abs(p1 - p2) < 1e-3
        if self.cascade:
            z1, z2 = np.roots(b).astype(complex) if b[0] != 0.0 else (0j, 0j)
            self._gain = b[0]
            self._zeros = (z1, z2)
            self._stages = (_FirstOrder(p1, 1.0, chunk), _FirstOrder(p2, 1.0, chunk))
            self._last_in = [0j, 0j]  # the previous input sample of each stage
            return
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
        if x.size == 0:
            return x.copy()
        if self.cascade:
            return self._cascade(x)
        y = x * self._direct
        for part in self._parts:
            y += self._weight * part(x).real
        return y

    def _cascade(self, x: np.ndarray) -> np.ndarray:
        u = x.astype(complex)
        for i, (stage, zero) in enumerate(zip(self._stages, self._zeros, strict=True)):
            shifted = np.concatenate(([self._last_in[i]], u[:-1]))
            self._last_in[i] = u[-1]
            u = stage(u - zero * shifted)
        return (self._gain * u).real
