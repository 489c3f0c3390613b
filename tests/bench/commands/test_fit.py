"""`rotorbench fit`: a bad window is refused; a multi-rate run fits without numpy warnings."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.cli import main
from tests.bench.conftest import imported_run
from tests.conftest import run_bad


@pytest.mark.parametrize("value", ["0", "-1", "nan"])
def test_fit_window_must_be_positive(tmp_path: Path, capsys, value: str) -> None:
    """--window nan ended in 'cannot convert float NaN to integer'."""
    run = imported_run(tmp_path)
    capsys.readouterr()
    err = run_bad(capsys, "fit", str(run), f"--window={value}")
    assert "--window: expected seconds > 0 after each edge" in err


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_fit_multi_rate_run_prints_no_numpy_warning(tmp_path: Path, capsys) -> None:
    """Load-cell rows at 250 Hz interleaved with telemetry rows (thrust empty) at 100 Hz,
    as the sim-can rig records: fit printed 'RuntimeWarning: Mean of empty slice'."""
    import numpy as np

    def command(t):
        return np.where((t >= 1.0) & (np.floor(t) % 2 == 1), 1700.0, 1500.0)

    fine = np.arange(0.0, 12.0, 0.0005)  # first-order lag, 12 ms delay, tau 30 ms
    target = (command(fine - 0.012) - 1000.0) / 250.0
    resp = np.zeros_like(fine)
    for i in range(1, fine.size):
        resp[i] = resp[i - 1] + (target[i] - resp[i - 1]) * (1 - np.exp(-0.0005 / 0.03))
    cell = np.arange(0.0, 12.0, 0.004)
    tele = np.arange(0.0013, 12.0, 0.01)
    rows = [(a, command(a), f"{np.interp(a, fine, resp):.5f}", "") for a in cell]
    rows += [(a, command(a), "", "5000") for a in tele]
    f = tmp_path / "mixed.csv"
    f.write_text("t_s,throttle_us,thrust_n,rpm\n" + "\n".join(
        f"{a:.4f},{u},{y},{r}" for a, u, y, r in sorted(rows)) + "\n")
    assert main(["import", str(f), "--format", "csv", "--out", str(tmp_path / "run")]) == 0
    assert main(["fit", str(tmp_path / "run"), "--json"]) == 0
    assert "Warning" not in capsys.readouterr().err
