"""Blackbox import speed: a synthesised 10-minute, 2 kHz Betaflight log (1.2 M frames).

The log is written by the tests' encoder (tests/analysis/blackbox_writer.py): one block
of segments is encoded frame by frame, then repeated with only the I frames' iteration
and time re-encoded (a P frame holds differences, so its bytes do not depend on the
absolute time). Prints the file size, the decode time of ``read_blackbox`` alone and of
the whole ``rotorbench import`` (decode + run folder; the CLI's one-off loading of its
command modules is timed apart, on a small log first), and frames per second, in CPU
time (the wall time also counts other processes on a shared machine).

blackbox_decode (blackbox-tools, GPL-3, C) is the reference decoder; it is on no package
registry this project uses (no PyPI wheel, no Debian package here), so no ratio to it is
printed. Usage: python benchmarks/flightlog_import.py [--minutes 10] [--rate 2000]
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from analysis.flightlogs.blackbox import read_blackbox  # noqa: E402
from bench.cli import main as cli  # noqa: E402


def _writer():
    spec = importlib.util.spec_from_file_location(
        "blackbox_writer", REPO / "tests" / "analysis" / "blackbox_writer.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["blackbox_writer"] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def synthesise(path: Path, frames: int, rate_hz: float) -> None:
    w = _writer()
    s = w.Settings(p_interval=max(1, round(8000 / rate_hz)), i_interval=32)
    lay = w.quad_layout()
    per_seg = s.i_interval // s.p_interval
    block_frames = min(frames, 64 * 1024 // per_seg * per_seg)
    rows = w.flight_rows(block_frames, lay, s)
    body = w.main_frames(rows, lay, s)
    segs = [body[k:k + per_seg] for k in range(0, len(body), per_seg)]
    i_rest = [w.encode_fields(rows[k * per_seg, 2:].tolist(), lay.i_enc[2:])
              for k in range(len(segs))]
    p_bytes = [b"".join(seg[1:]) for seg in segs]
    it_step, t_step = per_seg * s.p_interval, per_seg * s.p_interval * 125
    t_block = int(rows[-1, 1] - rows[0, 1]) + t_step - (int(rows[-1, 1] - rows[0, 1]) % t_step)
    with open(path, "wb") as fh:
        fh.write(w.header(lay, s))
        done, rep = 0, 0
        while done < frames:
            out = []
            for k in range(len(segs)):
                if done >= frames:
                    break
                it = int(rows[k * per_seg, 0]) + rep * len(segs) * it_step
                t = int(rows[k * per_seg, 1]) + rep * t_block
                out.append(b"I" + w.uvb(it) + w.uvb(t) + i_rest[k] + p_bytes[k])
                done += per_seg
            fh.write(b"".join(out))
            rep += 1
        fh.write(b"E\xffEnd of log\x00")


def run(minutes: float, rate_hz: float) -> None:
    frames = int(minutes * 60 * rate_hz)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "LOG00001.BFL"
        t0 = time.perf_counter()
        synthesise(path, frames, rate_hz)
        t_syn = time.perf_counter() - t0
        size = path.stat().st_size
        t0, c0 = time.perf_counter(), time.process_time()
        (log,) = read_blackbox(path)
        t_dec, c_dec = time.perf_counter() - t0, time.process_time() - c0
        assert np.all(np.diff(log.columns["t_s"]) > 0)
        small = Path(tmp) / "small.BFL"  # a first import loads every command module
        synthesise(small, 1000, rate_hz)
        c0 = time.process_time()
        cli(["import", str(small), "--out", str(Path(tmp) / "warm")])
        c_warm = time.process_time() - c0
        t0, c0 = time.perf_counter(), time.process_time()
        rc = cli(["import", str(path), "--out", str(Path(tmp) / "run")])
        t_imp, c_imp = time.perf_counter() - t0, time.process_time() - c0
    print(f"log: {minutes:g} min at {rate_hz:g} Hz, {log.rows} frames decoded of {frames} "
          f"written, {size / 1e6:.1f} MB (synthesised in {t_syn:.1f} s)")
    print(f"decode (read_blackbox): {c_dec:.2f} s CPU ({t_dec:.2f} s wall) = "
          f"{log.rows / c_dec / 1e6:.2f} M frames/s, {size / c_dec / 1e6:.1f} MB/s of CPU")
    print(f"rotorbench import (decode + run folder): {c_imp:.2f} s CPU ({t_imp:.2f} s wall), "
          f"exit {rc}")
    print(f"(the CLI's first call, a 1000-frame log, took {c_warm:.2f} s CPU: it imports "
          "every command module, more when Python may not write bytecode)")
    print(f"target, the import in under 10 s on one core: {'met' if c_imp < 10 else 'NOT met'} "
          "(CPU time: the wall time also counts other processes on a shared machine)")
    print("blackbox_decode (GPL-3 C reference): not on a package registry here, no ratio")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--rate", type=float, default=2000.0)
    a = ap.parse_args()
    run(a.minutes, a.rate)
