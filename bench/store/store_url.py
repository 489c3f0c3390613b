"""What ``--store`` names, and how a catalog's connection string is shown without its secret.

A folder path (the default ``runs``) is the embedded store. The lab catalog is a libpq
connection string in either of libpq's forms: a URL (``postgresql://`` or ``postgres://``)
or keyword=value words (``host=db.lab dbname=lab``, ``service=lab``). It is parsed by
libpq's own rules (psycopg's ``conninfo_to_dict``), never by a regular expression on the
text, so what is shown, compared and stored is what libpq connects to; a secret
(``password``, ``sslpassword``) is left out of everything shown. psycopg comes with the
``lab`` extra: without it a catalog is still recognised (by its scheme or first keyword),
and whatever needs to parse it names the extra. A folder store never needs psycopg.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import quote, urlsplit

from bench.errors import RigError

__all__ = ["LAB_EXTRA", "SECRET_KEYS", "STORE_ENV", "StoreUrl", "conninfo", "conninfo_text",
           "parse_store", "public_params", "redact", "scrub", "show_params"]

STORE_ENV = "ROTORBENCH_STORE"
LAB_EXTRA = "pip install 'rotorbench[lab]'"
SECRET_KEYS = ("password", "sslpassword")
_PG_SCHEMES = ("postgresql", "postgres")
#: a URL's start (RFC 3986 scheme, then ``://``): a libpq keyword string may hold ``://``
#: in a value (``password=999://``) and is no URL for it
_URL_START = re.compile(r"\s*([A-Za-z][A-Za-z0-9+.-]*)://")

# libpq's keywords (PostgreSQL 15, "Parameter Key Words"): a text whose first word is one
# of them followed by '=' is a keyword=value connection string, not a folder
_KEYWORDS = frozenset(
    "host hostaddr port dbname user password passfile channel_binding connect_timeout "
    "client_encoding options application_name fallback_application_name keepalives "
    "keepalives_idle keepalives_interval keepalives_count tcp_user_timeout replication "
    "gssencmode sslmode requiressl sslcompression sslcert sslkey sslpassword sslrootcert "
    "sslcrl sslcrldir sslsni requirepeer ssl_min_protocol_version ssl_max_protocol_version "
    "krbsrvname gsslib service target_session_attrs load_balance_hosts".split())
_NOT_ENCODED = ("a character of the password is not percent-encoded (# as %23, / as %2F, "
                "? as %3F, @ as %40, % as %25), or give the password in PGPASSWORD or "
                "~/.pgpass")


def _scheme(text: str) -> str | None:
    """The URL scheme of ``text`` (lower case), or None when it is no URL."""
    m = _URL_START.match(text)
    return m.group(1).lower() if m else None


@dataclass(frozen=True)
class StoreUrl:
    """A parsed ``--store``: ``folder`` for the embedded store, else ``dsn`` for PostgreSQL."""

    text: str
    folder: Path | None = None
    dsn: str | None = None

    @property
    def is_lab(self) -> bool:
        return self.dsn is not None

    def shown(self) -> str:
        """The store as it may be printed (any password as ``***``)."""
        return redact(self.text)


def parse_store(text: str | os.PathLike[str] | None, default: str = "runs") -> StoreUrl:
    """``--store`` (or ``$ROTORBENCH_STORE``, or ``default``) as a ``StoreUrl``; needs no
    psycopg (a catalog is only recognised here, parsed when it is opened)."""
    raw = str(text) if text is not None else os.environ.get(STORE_ENV) or default
    if _is_catalog(raw):
        return StoreUrl(raw, dsn=raw)
    scheme = _scheme(raw) or ""
    if scheme == "file":
        return StoreUrl(raw, folder=Path(urlsplit(raw).path))
    if scheme:
        raise RigError(f"--store {redact(raw)}: unknown kind {scheme!r}; give a folder or a "
                       "postgresql://user@host/db URL")
    return StoreUrl(raw, folder=Path(raw))


def _is_catalog(raw: str) -> bool:
    scheme = _scheme(raw)
    if scheme is not None:
        return scheme in _PG_SCHEMES
    key, eq, _ = raw.lstrip().partition("=")
    return bool(eq) and key.strip().lower() in _KEYWORDS


def conninfo(dsn: str) -> dict[str, str]:
    """``dsn`` parsed by libpq's rules into its parameters (password included). A text libpq
    cannot parse is refused without quoting it (libpq's message quotes the text around the
    fault, which may be the password); so is a URL whose password was not percent-encoded,
    which libpq reads as another host, port or database."""
    try:
        from psycopg.conninfo import conninfo_to_dict
    except ImportError:
        raise RigError(f"store {_hidden(dsn)}: the lab catalog needs psycopg: {LAB_EXTRA}"
                       ) from None
    import psycopg

    try:
        params = {k: str(v) for k, v in conninfo_to_dict(dsn).items() if v is not None}
    except (psycopg.Error, UnicodeDecodeError):  # '%99' decodes to no UTF-8
        raise RigError(f"store {_hidden(dsn)}: not a connection string libpq can read; "
                       f"{_NOT_ENCODED}") from None
    if _is_url(dsn) and _misread_url(dsn, params):
        raise RigError(f"store {_hidden(dsn)}: {_NOT_ENCODED}")
    return params


def _misread_url(dsn: str, params: dict[str, str]) -> bool:
    """True when libpq took part of a raw password for the host, port or database: an '@'
    that is not the one ending the user info, or a port that is no number."""
    after = dsn.split("://", 1)[1]
    authority = after.split("/", 1)[0]
    if after.count("@") > authority.count("@") or authority.count("@") > 1:
        return True
    if "@" in params.get("host", "") or "@" in params.get("dbname", ""):
        return True
    return any(p and not p.isdigit() for p in params.get("port", "").split(","))


def public_params(dsn: str) -> dict[str, str]:
    """The connection parameters of ``dsn`` without its secrets: what may be printed,
    compared and written into the spool."""
    return {k: v for k, v in conninfo(dsn).items() if k not in SECRET_KEYS}


def conninfo_text(params: Mapping[str, str]) -> str:
    """Connection parameters as a libpq keyword=value string (quoted by libpq's rules)."""
    from psycopg.conninfo import make_conninfo

    return make_conninfo("", **params)


def show_params(params: Mapping[str, str]) -> str:
    """Connection parameters as a URL that may be printed (any secret as ``***``)."""
    return _shown(dict(params), url=True)


def redact(text: str) -> str:
    """``text`` as it may be printed: a catalog's connection string rebuilt from its parsed
    parameters with every secret as ``***``; another URL with user info (``s3://K:S@b``)
    without it; anything else as it is. Never raises."""
    if _is_catalog(text):
        try:
            params = conninfo(text)
        except RigError:
            return _hidden(text)
        return _shown(params, url=_is_url(text))
    if _scheme(text) is not None and "@" in text:  # user info (a raw '/' in a secret ends
        # the netloc, so the last '@' is taken)
        scheme, rest = text.split("://", 1)
        return f"{scheme}://***@{rest.rsplit('@', 1)[1]}"
    return text


def _is_url(text: str) -> bool:
    return _scheme(text) is not None


def _hidden(text: str) -> str:
    """A catalog that cannot be parsed (or psycopg is missing): its kind, nothing else."""
    return "postgresql://…" if _is_url(text) else "(libpq connection string)"


def _shown(params: dict[str, str], *, url: bool) -> str:
    shown = {k: ("***" if k in SECRET_KEYS else v) for k, v in params.items()}
    if not url:
        return conninfo_text(shown)
    user = shown.pop("user", None)
    pw = shown.pop("password", None)
    host, port, db = shown.get("host", ""), shown.get("port", ""), shown.pop("dbname", None)
    netloc = ""
    if host and "," not in host and not host.startswith("/") and "," not in port:
        shown.pop("host")
        shown.pop("port", None)
        netloc = f"[{host}]" if ":" in host else quote(host, safe="")
        netloc += f":{port}" if port else ""
    if user is not None:
        netloc = f"{quote(user, safe='')}{':' + pw if pw else ''}@{netloc}"
    query = "&".join(f"{quote(k, safe='')}={quote(v, safe='/')}" for k, v in shown.items())
    path = f"/{quote(db, safe='')}" if db is not None else ""
    return f"postgresql://{netloc}{path}{'?' + query if query else ''}"


def scrub(message: str, dsn: str | None) -> str:
    """``message`` (e.g. a driver's error) with every secret of ``dsn`` removed: its
    parsed values, and their percent-encoded forms, wherever they appear."""
    if not dsn:
        return message
    try:
        params = conninfo(dsn)
    except RigError:
        return message.replace(dsn, _hidden(dsn))
    message = message.replace(dsn, redact(dsn))
    for key in SECRET_KEYS:
        secret = params.get(key)
        if secret:
            for form in {secret, quote(secret, safe=""), quote(secret)}:
                message = message.replace(form, "***")
    return message
