"""Run-list date filters: one check (``RunFilter``), the same answer from both stores and
from `rotorbench runs`: a date that is not one is refused in one line, exit 2."""

from __future__ import annotations

import pytest

from bench.cli import main
from bench.store.run_summary import BadFilter, RunFilter

BAD_DATES = ["2024-13-45", "2024-02-30", "yesterday", "2024-01-01T25:00", "'; DROP TABLE runs",
             "2024-01-01T00:00+99:00", "\x00", "9" * 200]


@pytest.mark.parametrize("bad", BAD_DATES)
@pytest.mark.parametrize("name", ["since", "until"])
def test_a_date_that_is_not_one_is_refused(bad: str, name: str) -> None:
    with pytest.raises(BadFilter, match=rf"^{name} .*: expected a date YYYY-MM-DD") as err:
        RunFilter(**{name: bad})
    assert len(str(err.value)) < 200 and "\x00" not in str(err.value)


@pytest.mark.parametrize(("given", "bound"), [
    ("2024-05-01", "2024-05-01T00:00:00.000+00:00"),
    ("2024-05-01T10:30", "2024-05-01T10:30:00.000+00:00"),
    ("2024-05-01T10:30:00Z", "2024-05-01T10:30:00.000+00:00"),
    ("2024-05-01T12:30:00+02:00", "2024-05-01T10:30:00.000+00:00"),
])
def test_dates_take_the_form_of_started_utc(given: str, bound: str) -> None:
    assert RunFilter(since=given).since == bound == RunFilter(until=given).until


@pytest.fixture(params=["folder", "lab"])
def store_url(request: pytest.FixtureRequest, tmp_path: object) -> str:
    """A store holding one imported run (started when it was imported: now)."""
    log = tmp_path / "stand.csv"
    log.write_text("t_s,throttle_us,thrust_n\n0,1000,0\n0.1,1100,0.5\n0.2,1200,1\n")
    folder = tmp_path / "runs"
    assert main(["import", str(log), "--format", "csv", "--out", str(folder / "r1")]) == 0
    assert main(["runs", "--rebuild", "--out", str(folder)]) == 0
    if request.param == "folder":
        return str(folder)
    pg_url = request.getfixturevalue("pg_url")
    assert main(["store", "init", pg_url, "--data", str(tmp_path / "lab")]) == 0
    assert main(["store", "push", str(folder), "--store", pg_url]) == 0
    return pg_url


def _listed(url: str, capsys: pytest.CaptureFixture[str], *args: str) -> list[str]:
    import json

    capsys.readouterr()
    assert main(["runs", "--store", url, "--json", *args]) == 0
    return [r["run_id"] for r in json.loads(capsys.readouterr().out)]


@pytest.mark.parametrize("bad", BAD_DATES[:4])
@pytest.mark.parametrize("option", ["--since", "--until"])
def test_runs_refuses_a_bad_date_in_one_line(store_url: str, bad: str, option: str,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    assert main(["runs", "--store", store_url, option, bad]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and err.startswith("rotorbench: error: ")
    assert f"{option} " in err and "expected a date" in err


def test_runs_filters_by_date_alike_in_both_stores(store_url: str,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    assert _listed(store_url, capsys, "--since", "2000-01-01") == ["r1"]
    assert _listed(store_url, capsys, "--since", "2999-01-01") == []
    assert _listed(store_url, capsys, "--until", "2000-01-01T00:00Z") == []
    assert _listed(store_url, capsys, "--since", "2000-01-01", "--until", "2999-12-31") \
        == ["r1"]
