"""What ``--store URL`` names, and how a URL is shown without its secret.

A folder path (the default ``runs``) is today's store: run folders with ``runs.sqlite``
and ``constants.sqlite`` beside them. ``postgresql://`` (or ``postgres://``) names the lab
catalog; libpq parameters (``sslmode``, ``service``, ``connect_timeout``) pass through as
they are. The password is never written anywhere: echoed URLs go through ``redact``.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlsplit, urlunsplit

from bench.errors import RigError

__all__ = ["STORE_ENV", "StoreUrl", "parse_store", "redact", "scrub"]

STORE_ENV = "ROTORBENCH_STORE"
_PG_SCHEMES = ("postgresql", "postgres")


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
        """The URL as it may be printed (password replaced by ``***``)."""
        return redact(self.text)


def parse_store(text: str | os.PathLike[str] | None, default: str = "runs") -> StoreUrl:
    """``--store`` (or ``$ROTORBENCH_STORE``, or ``default``) as a ``StoreUrl``."""
    raw = str(text) if text is not None else os.environ.get(STORE_ENV) or default
    scheme = urlsplit(raw).scheme.lower() if "://" in raw else ""
    if scheme in _PG_SCHEMES:
        return StoreUrl(raw, dsn=raw)
    if scheme == "file":
        return StoreUrl(raw, folder=Path(urlsplit(raw).path))
    if scheme:
        raise RigError(f"--store {redact(raw)}: unknown kind {scheme!r}; give a folder or a "
                       "postgresql://user@host/db URL")
    return StoreUrl(raw, folder=Path(raw))


def redact(url: str) -> str:
    """``url`` with any password (``user:pw@``, ``password=...``) replaced by ``***``."""
    if "://" in url:
        parts = urlsplit(url)
        if parts.password is not None:
            host = parts.hostname or ""
            if parts.port is not None:
                host = f"{host}:{parts.port}"
            netloc = f"{parts.username or ''}:***@{host}"
            url = urlunsplit((parts.scheme, netloc, parts.path, parts.query, parts.fragment))
    return re.sub(r"(password\s*=\s*)('[^']*'|[^\s&]+)", r"\1***", url, flags=re.I)


def scrub(message: str, url: str | None) -> str:
    """``message`` (e.g. a driver's error) with the password of ``url`` removed."""
    secret = _password(url) if url else None
    message = redact(message)
    return message.replace(secret, "***") if secret else message


def _password(url: str) -> str | None:
    if "://" in url:
        pw = urlsplit(url).password
        if pw:
            return pw
    m = re.search(r"password\s*=\s*('([^']*)'|[^\s&]+)", url, flags=re.I)
    if m:
        return m.group(2) if m.group(2) is not None else m.group(1)
    return None
