"""The lab catalog's index in PostgreSQL (psycopg 3): runs and constants of every bench.

Every call opens a short connection (a bench PC may lose the network between two calls)
and turns the server's answers into one-line ``RigError``s with the password scrubbed:
a missing schema says to run ``store init``, a missing privilege names it and the role
that has it. Run rows are upserted by id (a retried upload never duplicates a run);
constants are appended in one transaction per ``add_constants`` and never changed.
"""

from __future__ import annotations

import contextlib
import json
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from bench.errors import RigError
from bench.store.json_values import json_safe
from bench.store.pg_schema import (
    CATALOG_ID_SETTING,
    READER_ROLE,
    SCHEMA_VERSION,
    WRITER_ROLE,
    schema_version,
)
from bench.store.run_summary import RunFilter
from bench.store.store_url import conninfo, public_params, redact, scrub

__all__ = ["CatalogIdentity", "CatalogRun", "CatalogUnavailable", "LabCatalog",
           "StoredConstants"]

#: what a login needs for each kind of work, said when the server refuses it
RECORD_NEEDS = f"recording needs the {WRITER_ROLE} role, reading {READER_ROLE}"
INIT_NEEDS = ("store init needs a login that may create tables in this database (its owner) "
              "and create roles (CREATEROLE), e.g. the admin login of docs/lab.md")

RUN_FIELDS = ("run_id", "bench", "operator", "host", "rig", "rig_sha256", "software_version",
              "sequence", "components", "status", "reason", "started_utc", "ended_utc",
              "samples", "data", "meta")


class CatalogUnavailable(RigError):
    """The database could not be reached (network, server down): a bench spools instead."""


@dataclass(frozen=True)
class CatalogIdentity:
    """Which catalog a connection reached: its UUID (``store init`` wrote it) and where
    libpq actually connected (host, port, dbname: a service or a default resolved)."""

    catalog_id: str
    address: dict[str, str]
    user: str
    can_record: bool


@dataclass(frozen=True)
class CatalogRun:
    """One run as the catalog lists it (``data``: where its run folder lives)."""

    run_id: str
    bench: str
    operator: str
    host: str
    rig: str
    rig_sha256: str
    software_version: str
    sequence: str
    components: dict[str, Any]
    status: str
    reason: str
    started_utc: str | None
    ended_utc: str | None
    samples: int
    data: str
    meta: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        out = {k: getattr(self, k) for k in RUN_FIELDS if k != "meta"}
        return out


@dataclass(frozen=True)
class StoredConstants:
    """One fitted constants row (as ``constants_store.ConstantsRow``, plus who and when)."""

    motor: str
    propeller: str
    esc: str
    esc_mode: str
    battery: str
    kind: str
    catalog: str
    run_id: str
    run_path: str
    fitted_utc: str
    data: dict[str, Any]
    recorded_by: str = ""


class LabCatalog:
    """The PostgreSQL index at ``dsn`` (a URL or libpq string; libpq options pass through)."""

    def __init__(self, dsn: str, connect_timeout_s: float = 5.0) -> None:
        conninfo(dsn)  # psycopg missing or a text libpq cannot read: said here, in one line
        self.dsn = dsn
        self.connect_timeout_s = connect_timeout_s

    @property
    def params(self) -> dict[str, str]:
        """The connection parameters without secrets (what the spool may keep)."""
        return public_params(self.dsn)

    def __repr__(self) -> str:  # never the password, even in a traceback's locals
        return f"LabCatalog({redact(self.dsn)!r})"

    # -- connections --------------------------------------------------------------------
    @contextlib.contextmanager
    def connect(self, *, check_schema: bool = True, needs: str = RECORD_NEEDS
                ) -> Iterator[Any]:
        """A short autocommit connection; server errors become one-line ``RigError``s
        (``needs``: what to say when the server refuses a privilege)."""
        import psycopg

        try:
            con = psycopg.connect(self.dsn, autocommit=True,
                                  connect_timeout=max(1, math.ceil(self.connect_timeout_s)),
                                  application_name="rotorbench")
        except psycopg.OperationalError as exc:
            raise CatalogUnavailable(f"store {redact(self.dsn)}: cannot connect "
                                     f"({scrub(_first_line(exc), self.dsn)})") from None
        except psycopg.ProgrammingError as exc:  # malformed connection string
            raise RigError(f"store {redact(self.dsn)}: {scrub(_first_line(exc), self.dsn)}"
                           ) from None
        try:
            if check_schema:
                have = schema_version(con)
                if have == 0:
                    raise RigError(f"store {redact(self.dsn)}: no rotorbench catalog in this "
                                   "database; create it with `rotorbench store init URL`")
                if have < SCHEMA_VERSION:
                    raise RigError(f"store {redact(self.dsn)}: catalog schema {have} is older "
                                   f"than this rotorbench's {SCHEMA_VERSION}; upgrade it with "
                                   "`rotorbench store init URL`")
                if have > SCHEMA_VERSION:
                    raise RigError(f"store {redact(self.dsn)}: catalog schema {have} is newer "
                                   f"than this rotorbench's {SCHEMA_VERSION}; upgrade rotorbench")
            yield con
        except psycopg.errors.InsufficientPrivilege as exc:
            raise RigError(f"store {redact(self.dsn)}: permission denied "
                           f"({scrub(_first_line(exc), self.dsn)}); {needs}") from None
        except psycopg.OperationalError as exc:
            raise CatalogUnavailable(f"store {redact(self.dsn)}: connection lost "
                                     f"({scrub(_first_line(exc), self.dsn)})") from None
        except psycopg.Error as exc:
            raise RigError(f"store {redact(self.dsn)}: {scrub(_first_line(exc), self.dsn)}"
                           ) from None
        finally:
            con.close()

    def init(self) -> tuple[int, int]:
        """Create or upgrade the schema and roles; (version before, version after)."""
        from bench.store.pg_schema import init_schema

        with self.connect(check_schema=False, needs=INIT_NEEDS) as con:
            return init_schema(con)

    def identity(self) -> CatalogIdentity:
        """The catalog's UUID, where the connection went, and whether the login may record."""
        with self.connect() as con:
            row = con.execute(
                "SELECT (SELECT value FROM settings WHERE key = %s), current_user, "
                "has_table_privilege(current_user, 'runs', 'INSERT')",
                (CATALOG_ID_SETTING,)).fetchone()
            info = con.info
            address = {"host": str(info.host), "port": str(info.port),
                       "dbname": str(info.dbname)}
        return CatalogIdentity(str(row[0]), address, str(row[1]), bool(row[2]))

    def check_can_record(self) -> CatalogIdentity:
        """Refuse (exit 2, naming the permission) a login that cannot insert runs; called
        before anything spins or is uploaded. Returns the catalog's identity."""
        ident = self.identity()
        if not ident.can_record:
            raise RigError(f"store {redact(self.dsn)}: user {ident.user} may not record runs "
                           f"(no INSERT on table runs); grant it the {WRITER_ROLE} role")
        return ident

    # -- settings -----------------------------------------------------------------------
    def setting(self, key: str) -> str | None:
        with self.connect() as con:
            row = con.execute("SELECT value FROM settings WHERE key = %s", (key,)).fetchone()
        return None if row is None else str(row[0])

    def set_setting(self, key: str, value: str) -> None:
        with self.connect() as con:
            con.execute("INSERT INTO settings (key, value) VALUES (%s, %s) ON CONFLICT (key) "
                        "DO UPDATE SET value = EXCLUDED.value", (key, value))

    # -- runs ---------------------------------------------------------------------------
    def upsert_run(self, run: CatalogRun) -> None:
        """Insert the run or update its row (same id): retries never duplicate a run."""
        from psycopg.types.json import Jsonb

        values = [getattr(run, k) for k in RUN_FIELDS]
        values[RUN_FIELDS.index("components")] = Jsonb(json_safe(run.components))
        values[RUN_FIELDS.index("meta")] = Jsonb(json_safe(run.meta))
        cols = ", ".join(RUN_FIELDS)
        marks = ", ".join(["%s"] * len(RUN_FIELDS))
        updates = ", ".join(f"{k} = EXCLUDED.{k}" for k in RUN_FIELDS if k != "run_id")
        with self.connect() as con:
            owner = con.execute("SELECT owner, current_user FROM runs WHERE run_id = %s",
                                (run.run_id,)).fetchone()
            if owner is not None and owner[0] != owner[1]:
                raise RigError(f"run {run.run_id}: recorded in {redact(self.dsn)} by login "
                               f"{owner[0]}; login {owner[1]} may not change it (deliver it "
                               f"as {owner[0]})")
            con.execute(f"INSERT INTO runs ({cols}) VALUES ({marks}) ON CONFLICT (run_id) DO "
                        f"UPDATE SET {updates}, updated_utc = now()", values)

    def list_runs(self, where: RunFilter | None = None, *, limit: int | None = None,
                  offset: int = 0) -> list[CatalogRun]:
        """Runs newest first, narrowed by ``where``; every value is a bound parameter."""
        clause, params = _filters(where or RunFilter())
        sql = (f"SELECT {', '.join(RUN_FIELDS[:-1])} FROM runs {clause} "
               "ORDER BY started_utc DESC NULLS LAST, run_id DESC")
        if limit is not None:
            sql += " LIMIT %s OFFSET %s"
            params += [int(limit), int(offset)]
        with self.connect() as con:
            rows = con.execute(sql, params).fetchall()
        return [_run(r) for r in rows]

    def count_runs(self, where: RunFilter | None = None) -> int:
        clause, params = _filters(where or RunFilter())
        with self.connect() as con:
            return int(con.execute(f"SELECT count(*) FROM runs {clause}", params).fetchone()[0])

    def get_run(self, run_id: str) -> CatalogRun | None:
        with self.connect() as con:
            row = con.execute(f"SELECT {', '.join(RUN_FIELDS)} FROM runs WHERE run_id = %s",
                              (run_id,)).fetchone()
        return None if row is None else _run(row[:-1], meta=row[-1])

    # -- constants ----------------------------------------------------------------------
    def add_constants(self, rows: Sequence[StoredConstants]) -> int:
        """Append ``rows`` in one transaction (all or none); returns how many."""
        from psycopg.types.json import Jsonb

        with self.connect() as con, con.transaction():
            for r in rows:
                con.execute(
                    "INSERT INTO constants (motor, propeller, esc, esc_mode, battery, kind, "
                    "catalog, run_id, run_path, data) VALUES (%s,%s,%s,%s,%s,%s,%s,%s,%s,%s)",
                    (r.motor, r.propeller, r.esc, r.esc_mode, r.battery, r.kind, r.catalog,
                     r.run_id, r.run_path, Jsonb(json_safe(r.data))))
        return len(rows)

    def constants(self, *, history: bool = False) -> list[StoredConstants]:
        """The newest constants per actuator and kind, or every row ever added."""
        table = "constants" if history else "constants_current"
        with self.connect() as con:
            rows = con.execute(
                "SELECT motor, propeller, esc, esc_mode, battery, kind, catalog, run_id, "
                f"run_path, fitted_utc, data, recorded_by FROM {table} ORDER BY motor, "
                "propeller, esc, esc_mode, battery, kind, id").fetchall()
        return [StoredConstants(*r[:9], fitted_utc=r[9].isoformat(timespec="seconds"),
                                data=dict(r[10]), recorded_by=str(r[11])) for r in rows]


def _filters(where: RunFilter) -> tuple[str, list[Any]]:
    return where.sql("%s", "components->>%s = %s", columns=("bench", "status", "sequence"),
                     time_cast="::timestamptz")


def _run(row: Sequence[Any], meta: Any = None) -> CatalogRun:
    vals = list(row)
    for i in (RUN_FIELDS.index("started_utc"), RUN_FIELDS.index("ended_utc")):
        vals[i] = vals[i].isoformat(timespec="milliseconds") if vals[i] is not None else None
    vals[RUN_FIELDS.index("components")] = dict(vals[RUN_FIELDS.index("components")] or {})
    return CatalogRun(*vals, meta=dict(meta or {}))


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def run_from_meta(meta: Mapping[str, Any], *, data: str, samples: int,
                  bench: str, operator: str) -> CatalogRun:
    """A catalog row from a run's ``run.json`` content."""
    rig = meta.get("rig")
    seq = meta.get("sequence")
    return CatalogRun(
        run_id=str(meta["id"]), bench=bench, operator=operator,
        host=str(meta.get("host") or ""),
        rig=str(rig.get("name", "") if isinstance(rig, Mapping) else rig or ""),
        rig_sha256=str((rig.get("sha256") if isinstance(rig, Mapping) else None)
                       or meta.get("rig_sha256") or ""),
        software_version=str(meta.get("software_version") or ""),
        sequence=str(seq.get("name", "") if isinstance(seq, Mapping) else seq or ""),
        components=dict(meta.get("components") or {}),
        status=str(meta.get("status") or "unknown"), reason=str(meta.get("reason") or ""),
        started_utc=meta.get("started_utc"), ended_utc=meta.get("ended_utc"),
        samples=int(samples), data=data, meta=json.loads(json.dumps(meta, default=str)))
