"""The lab catalog's tables in PostgreSQL, as numbered migrations.

``rotorbench store init URL`` applies the migrations the database does not have yet, in
one transaction each, under an advisory lock (two benches running ``init`` at once do not
race), and creates two group roles:

* ``rotorbench_writer``: reads everything, inserts runs and constants, and updates only
  its own runs (row-level security on ``owner``); no delete.
* ``rotorbench_reader``: reads only.

The catalog's identity (``settings.catalog_id``, a UUID) is written by the migration that
adds it and by nobody else: the writer and reader roles may only read ``settings``.

Running ``init`` again changes nothing. Constants are never updated in place: every fit
is a new row of ``constants`` and ``constants_current`` shows the newest per actuator and
kind, so the history of every constant stays.
"""

from __future__ import annotations

from typing import Any

__all__ = ["CATALOG_ID_SETTING", "MIGRATIONS", "READER_ROLE", "SCHEMA_VERSION", "WRITER_ROLE",
           "init_schema", "schema_version"]

WRITER_ROLE = "rotorbench_writer"
READER_ROLE = "rotorbench_reader"
_LOCK_KEY = 0x726F746F72  # "rotor": the advisory lock of init
CATALOG_ID_SETTING = "catalog_id"

MIGRATIONS: tuple[str, ...] = (
    # 1: runs, constants with history, settings (the default data location)
    """
    CREATE TABLE runs (
        run_id text PRIMARY KEY,
        bench text NOT NULL,
        operator text NOT NULL,
        host text NOT NULL DEFAULT '',
        rig text NOT NULL DEFAULT '',
        rig_sha256 text NOT NULL DEFAULT '',
        software_version text NOT NULL DEFAULT '',
        sequence text NOT NULL DEFAULT '',
        components jsonb NOT NULL DEFAULT '{}',
        status text NOT NULL,
        reason text NOT NULL DEFAULT '',
        started_utc timestamptz,
        ended_utc timestamptz,
        samples bigint NOT NULL DEFAULT 0,
        data text NOT NULL DEFAULT '',
        meta jsonb NOT NULL DEFAULT '{}',
        owner name NOT NULL DEFAULT current_user,
        updated_utc timestamptz NOT NULL DEFAULT now()
    );
    CREATE INDEX runs_started ON runs (started_utc DESC, run_id);
    CREATE INDEX runs_bench ON runs (bench);
    CREATE INDEX runs_status ON runs (status);
    CREATE TABLE constants (
        id bigserial PRIMARY KEY,
        motor text NOT NULL,
        propeller text NOT NULL,
        esc text NOT NULL,
        esc_mode text NOT NULL,
        battery text NOT NULL,
        kind text NOT NULL CHECK (kind IN ('step', 'static')),
        catalog text NOT NULL DEFAULT '',
        run_id text NOT NULL,
        run_path text NOT NULL,
        fitted_utc timestamptz NOT NULL DEFAULT now(),
        data jsonb NOT NULL,
        recorded_by name NOT NULL DEFAULT current_user
    );
    CREATE INDEX constants_key ON constants (motor, propeller, esc, esc_mode, battery, kind, id);
    CREATE VIEW constants_current AS
        SELECT DISTINCT ON (motor, propeller, esc, esc_mode, battery, kind) *
        FROM constants
        ORDER BY motor, propeller, esc, esc_mode, battery, kind, id DESC;
    CREATE TABLE settings (key text PRIMARY KEY, value text NOT NULL);
    """,
    # 2: the catalog's identity, a UUID written once: a spooled run records it before it
    # starts and is delivered to this catalog only, however its URL is spelled at sync
    f"""
    INSERT INTO settings (key, value) VALUES ('{CATALOG_ID_SETTING}', gen_random_uuid()::text)
        ON CONFLICT (key) DO NOTHING;
    """,
)
SCHEMA_VERSION = len(MIGRATIONS)

_ROLES = f"""
DO $$
BEGIN
    IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = '{WRITER_ROLE}') THEN
        CREATE ROLE {WRITER_ROLE} NOLOGIN;
    END IF;
    IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = '{READER_ROLE}') THEN
        CREATE ROLE {READER_ROLE} NOLOGIN;
    END IF;
END
$$;
GRANT USAGE ON SCHEMA public TO {WRITER_ROLE}, {READER_ROLE};
GRANT SELECT ON runs, constants, constants_current, settings, rotorbench_schema
    TO {WRITER_ROLE}, {READER_ROLE};
GRANT INSERT, UPDATE ON runs TO {WRITER_ROLE};
GRANT INSERT ON constants TO {WRITER_ROLE};
GRANT USAGE ON SEQUENCE constants_id_seq TO {WRITER_ROLE};
ALTER TABLE runs ENABLE ROW LEVEL SECURITY;
DROP POLICY IF EXISTS runs_read ON runs;
DROP POLICY IF EXISTS runs_add ON runs;
DROP POLICY IF EXISTS runs_own ON runs;
CREATE POLICY runs_read ON runs FOR SELECT USING (true);
CREATE POLICY runs_add ON runs FOR INSERT TO {WRITER_ROLE} WITH CHECK (owner = current_user);
CREATE POLICY runs_own ON runs FOR UPDATE TO {WRITER_ROLE}
    USING (owner = current_user) WITH CHECK (owner = current_user);
"""


def schema_version(con: Any) -> int:
    """The applied migration count (0 for an empty database)."""
    row = con.execute("SELECT to_regclass('rotorbench_schema')").fetchone()
    if row is None or row[0] is None:
        return 0
    got = con.execute("SELECT max(version) FROM rotorbench_schema").fetchone()
    return int(got[0] or 0)


def init_schema(con: Any) -> tuple[int, int]:
    """Apply missing migrations and (re)grant the roles; returns (before, after) versions.

    ``con`` is a psycopg connection in autocommit mode; each migration is its own
    transaction, so a failure leaves the database at the last whole version."""
    con.execute("SELECT pg_advisory_lock(%s)", (_LOCK_KEY,))
    try:
        with con.transaction():
            con.execute("CREATE TABLE IF NOT EXISTS rotorbench_schema ("
                        "version integer PRIMARY KEY, applied_utc timestamptz NOT NULL "
                        "DEFAULT now())")
        before = schema_version(con)
        for number, sql in enumerate(MIGRATIONS[before:], start=before + 1):
            with con.transaction():
                con.execute(sql)
                con.execute("INSERT INTO rotorbench_schema (version) VALUES (%s)", (number,))
        with con.transaction():
            con.execute(_ROLES)
        return before, schema_version(con)
    finally:
        con.execute("SELECT pg_advisory_unlock(%s)", (_LOCK_KEY,))
