"""``--store`` as libpq reads it: both forms of a connection string, redaction by
structure for any password, and a folder store without psycopg."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from urllib.parse import quote

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from psycopg.conninfo import make_conninfo

from bench.errors import RigError
from bench.store.store_url import conninfo, parse_store, redact, scrub

SPECIAL = "#/?@%:&=+ '\"\\;~!$,[]{}<>|^`"
PASSWORDS = st.text(alphabet=SPECIAL + "aZ9-_.", min_size=6, max_size=24).filter(
    lambda p: sum(c in SPECIAL for c in p) >= 3)


@given(PASSWORDS)
@settings(max_examples=300, deadline=None)
def test_no_password_survives_redaction_in_any_form(password: str) -> None:
    url = f"postgresql://bench_a:{quote(password, safe='')}@db.lab:5433/lab?sslmode=require"
    keywords = make_conninfo("", host="db.lab", port="5433", dbname="lab", user="bench_a",
                             password=password)
    raw = f"postgresql://bench_a:{password}@db.lab:5433/lab"  # as a careless user types it
    for text in (url, keywords, raw, f"host=db.lab password={password}"):
        shown = redact(text)  # never raises
        assert password not in shown and quote(password, safe="") not in shown, (text, shown)
    assert redact(url) == "postgresql://bench_a:***@db.lab:5433/lab?sslmode=require"
    assert conninfo(url)["password"] == password == conninfo(keywords)["password"]
    message = f"FATAL: password {password!r} in {url} refused"
    assert password not in scrub(message, url) and quote(password, safe="") not in \
        scrub(message, url)


@pytest.mark.parametrize("raw", ["postgresql://u:pa/ss@h/db", "postgresql://u:p@w@h/db",
                                 "postgresql://u:pa%ss@h/db", "postgresql://u:pa ss@h/db",
                                 "host=h password='unclosed"])
def test_a_password_libpq_would_misread_is_one_line_without_it(raw: str) -> None:
    with pytest.raises(RigError) as err:
        conninfo(raw)
    text = str(err.value)
    assert "\n" not in text and "ss@" not in text and "unclosed" not in text
    assert "p@w" not in text and "w@h" not in text


def test_both_libpq_forms_and_a_service_are_catalogs_not_folders() -> None:
    for text in ("service=lab", "host=db.lab dbname=lab user=bench_a",
                 "postgres://db.lab/lab", " dbname = lab"):
        store = parse_store(text)
        assert store.is_lab and store.folder is None, text
    assert redact("service=lab") == "service=lab"
    assert parse_store("runs=2026").folder == Path("runs=2026")  # no libpq keyword
    assert parse_store("./runs").folder == Path("runs")
    assert redact("s3://KEY:SE/CRET@bucket/runs") == "s3://***@bucket/runs"


def test_without_psycopg_a_folder_store_works_and_a_catalog_names_the_extra(
        tmp_path: Path) -> None:
    """psycopg made unimportable, as on an install without the lab extra."""
    prelude = "import sys; sys.modules['psycopg'] = None\nfrom bench.cli import main\n"
    folder = subprocess.run(
        [sys.executable, "-c", prelude + f"sys.exit(main(['step', '--repeats', '1', "
         f"'--store', {str(tmp_path / 'runs')!r}]))"], capture_output=True, text=True,
        timeout=180)
    assert folder.returncode == 0, folder.stderr
    for store in ("postgresql://bench:pw-secret@db.lab/lab", "service=lab"):
        lab = subprocess.run(
            [sys.executable, "-c", prelude + f"sys.exit(main(['runs', '--store', {store!r}]))"],
            capture_output=True, text=True, timeout=120)
        assert lab.returncode == 2 and "pip install 'rotorbench[lab]'" in lab.stderr, lab.stderr
        assert "Traceback" not in lab.stderr and "pw-secret" not in lab.stderr
        assert len(lab.stderr.strip().splitlines()) == 1


def test_a_keyword_string_whose_password_holds_a_url_start_is_still_redacted() -> None:
    """``://`` inside a value is no URL: the text is a libpq keyword string all the same
    (hypothesis found ``password=999://`` shown as typed)."""
    for text in ("host=db.lab password=999://", "dbname=lab password=a://b@c"):
        shown = redact(text)
        assert "999" not in shown and "a://b" not in shown, shown
        assert parse_store(text).is_lab
    assert redact("s3://KEY:SECRET@bucket/x") == "s3://***@bucket/x"
