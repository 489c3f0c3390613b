"""PNG figures of a run's vibration (``analysis.vibration``): level against speed, and the
spectrum with the rotor and blade-pass frequencies marked. Written like
``analysis.figures`` (Agg backend, temporary file renamed into place)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from analysis.figures import save_figure
from analysis.vibration import VibrationCurve, VibrationSpectrum

__all__ = ["plot_vibration_spectrum", "plot_vibration_speed"]


def plot_vibration_speed(curve: VibrationCurve, path: Path, title: str = "") -> Path:
    """Vibration level per speed bin (Tyto's 'vibration vs speed')."""
    fig, ax = plt.subplots(figsize=(6, 3.6))
    ax.plot(curve.rpm, curve.level_m_s2, "o-", ms=4)
    ax.set_xlabel("speed [rpm]")
    ax.set_ylabel(f"vibration [m/s²] ({curve.kind})")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.set_title(title or f"Vibration against speed: {curve.source}", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path)


def plot_vibration_spectrum(spec: VibrationSpectrum, path: Path, title: str = "") -> Path:
    """Welch PSD on a log scale, rotor and blade-pass frequencies as dashed lines."""
    fig, ax = plt.subplots(figsize=(7, 3.8))
    top = min(spec.fs_hz / 2, 4.0 * spec.blade_pass_hz)
    band = (spec.f_hz > 0) & (spec.f_hz <= top)
    ax.semilogy(spec.f_hz[band], spec.psd[band], lw=0.9)
    ax.axvline(spec.rotor_hz, color="C1", ls="--",
               label=f"rotor {spec.rotor_hz:.1f} Hz ({spec.rpm:.0f} rpm)")
    ax.axvline(spec.blade_pass_hz, color="C2", ls="--",
               label=f"blade pass {spec.blade_pass_hz:.1f} Hz ({spec.blades} blades)")
    ax.set_xlim(0, top)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"PSD of {spec.column} [(m/s²)²/Hz]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title(title or f"Vibration spectrum, {spec.t0_s:.1f}-{spec.t1_s:.1f} s, "
                          f"{spec.fs_hz:.0f} Hz sampling", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path)
