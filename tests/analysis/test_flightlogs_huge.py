"""Huge flight-log files are streamed, never read whole: a 2.2 GB sparse file (a short
blackbox log, then zeros) imports in bounded memory; a ULog beyond the reader's limit is
refused in one line. Each runs the real command in a child process and reads its peak
memory."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
HUGE = 2_200_000_000  # bytes: more than 2 GB
PEAK_MAX_MB = 600  # a child that read the file whole would hold > 2000 MB


def _import(path: Path, out: Path) -> tuple[subprocess.CompletedProcess[str], float]:
    # VmHWM: this process's own peak resident size. Not getrusage's ru_maxrss, which Linux
    # keeps across exec: it would report the forking test process's size
    code = ("import sys; from bench.cli import main; rc = main(sys.argv[1:]); "
            "print('PEAK', next(line.split()[1] for line in open('/proc/self/status') "
            "if line.startswith('VmHWM:'))); sys.exit(rc)")
    proc = subprocess.run([sys.executable, "-c", code, "import", str(path), "--out", str(out)],
                          capture_output=True, text=True, cwd=REPO, timeout=300)
    peak_kb = next(int(line.split()[1]) for line in proc.stdout.splitlines()
                   if line.startswith("PEAK"))
    return proc, peak_kb / 1024


def _sparse(path: Path, head: bytes, size: int = HUGE) -> None:
    with open(path, "wb") as fh:
        fh.write(head)
        fh.truncate(size)


bbw = sys.modules["rotorbench_tests_blackbox_writer"]  # blackbox_writer.py, loaded by conftest.py
dfw = sys.modules["rotorbench_tests_dataflash_writer"]  # dataflash_writer.py, loaded by conftest.py


def _blackbox() -> tuple[bytes, int]:
    lay, s = bbw.quad_layout(), bbw.Settings()
    # no LOG_END: the reader must scan the whole zero tail for more frames
    return bbw.blackbox_log(bbw.flight_rows(2000, lay, s), lay, s, end=False), 1999


def _dataflash() -> tuple[bytes, int]:
    data, truth = dfw.flight(500)
    return data, len(truth["t_us"])


@pytest.mark.slow(wall_s=60)
@pytest.mark.parametrize(("make", "size"), [(_blackbox, HUGE), (_dataflash, HUGE // 2)],
                         ids=["blackbox", "dataflash"])
def test_a_huge_file_is_streamed_in_bounded_memory(tmp_path, make, size):
    """The DataFlash file is half as big (1.1 GB): the same windowed reading, less time."""
    head, rows = make()
    path = tmp_path / "huge.log"
    _sparse(path, head, size)
    proc, peak_mb = _import(path, tmp_path / "r")
    assert proc.returncode == 0, proc.stderr[-500:]
    assert f"imported {rows} rows" in proc.stdout
    assert peak_mb < PEAK_MAX_MB, f"peak {peak_mb:.0f} MB"
    print(f"peak {peak_mb:.0f} MB")
    assert "Traceback" not in proc.stderr


def test_a_ulog_beyond_the_limit_is_refused_in_one_line(tmp_path):
    path = tmp_path / "huge.ulg"
    _sparse(path, b"ULog\x01\x12\x35\x01" + bytes(8))
    proc, peak_mb = _import(path, tmp_path / "r")
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1 and "GiB" in proc.stderr
    assert peak_mb < PEAK_MAX_MB
