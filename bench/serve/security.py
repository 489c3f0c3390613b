"""The web view's guards: token, size limits, and the headers every response carries.

* ``--token``: required on every request when set (``Authorization: Bearer TOKEN``, the
  scheme in any case as RFC 7235 has it, the ``X-Rotorbench-Token`` header, or the
  ``rotorbench_token`` cookie that ``/login`` sets for the right token only), compared in
  constant time.
* A query string over ``MAX_QUERY`` bytes or a path over ``MAX_PATH`` is 414, before any
  route runs.
* Every response has a Content-Security-Policy that allows only this server's scripts
  (plotly.js is served from the plotly package itself: no CDN, nothing copied here).
"""

from __future__ import annotations

import hmac
from collections.abc import Awaitable, Callable
from typing import Any

__all__ = ["COOKIE", "CSP", "MAX_PATH", "MAX_QUERY", "Guard", "token_matches"]

MAX_QUERY = 2048
MAX_PATH = 1024
COOKIE = "rotorbench_token"
CSP = ("default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; "
       "img-src 'self' data:; connect-src 'self'; object-src 'none'; base-uri 'none'; "
       "frame-ancestors 'none'; form-action 'self'")
_HEADERS = [(b"content-security-policy", CSP.encode()),
            (b"x-content-type-options", b"nosniff"),
            (b"referrer-policy", b"no-referrer"),
            (b"x-frame-options", b"DENY")]

Receive = Callable[[], Awaitable[dict[str, Any]]]
Send = Callable[[dict[str, Any]], Awaitable[None]]


class Guard:
    """ASGI middleware: size limits, the token, and the security headers."""

    def __init__(self, app: Any, token: str | None) -> None:
        self.app = app
        self.token = token

    async def __call__(self, scope: dict[str, Any], receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return

        async def send_with_headers(message: dict[str, Any]) -> None:
            if message["type"] == "http.response.start":
                message = {**message, "headers": [*message.get("headers", []), *_HEADERS]}
            await send(message)

        if len(scope.get("query_string", b"")) > MAX_QUERY or \
                len(scope.get("raw_path", b"") or b"") > MAX_PATH:
            await _plain(send_with_headers, 414, "request too long")
            return
        if self.token is not None and not self._authorised(scope):
            if scope["path"] == "/login":
                await self.app(scope, receive, send_with_headers)
                return
            await _plain(send_with_headers, 401, "token required: open /login?token=TOKEN or "
                         "send Authorization: Bearer TOKEN")
            return
        await self.app(scope, receive, send_with_headers)

    def _authorised(self, scope: dict[str, Any]) -> bool:
        assert self.token is not None
        for name, value in scope.get("headers", []):
            if name == b"authorization":
                scheme, _, credentials = value.strip().partition(b" ")
                if scheme.lower() == b"bearer" and token_matches(credentials.strip(),
                                                                 self.token):
                    return True
            elif name == b"x-rotorbench-token":
                if token_matches(value.strip(), self.token):
                    return True
            elif name == b"cookie":
                for part in value.split(b";"):
                    key, _, val = part.strip().partition(b"=")
                    if key == COOKIE.encode() and token_matches(val, self.token):
                        return True
        return False


def token_matches(given: bytes, token: str) -> bool:
    """``given`` is the server's token (constant time: no timing tells how much of it
    matched)."""
    return hmac.compare_digest(given, token.encode())


async def _plain(send: Send, status: int, text: str) -> None:
    body = text.encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"text/plain; charset=utf-8"),
                            (b"content-length", str(len(body)).encode())]})
    await send({"type": "http.response.body", "body": body})
