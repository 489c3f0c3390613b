"""Is a Dask scheduler there? A bounded look at ``--scheduler``'s first message.

``distributed`` bounds the TCP connect, not its handshake: it reads the peer's first
message with no deadline (by design) and allocates whatever length the first 8 bytes
claim. An HTTP server there waits for a request line that never ends, so the client
hangs; a server sending other bytes makes it allocate up to exabytes. A scheduler
writes its handshake (a small msgpack map) as soon as a connection opens, so before the
client connects this reads that message over a plain socket, with a deadline and a size
limit, and decodes it as Dask does: anything else is refused in one line (exit 2).

Only ``tcp://`` addresses (and bare ``host:port``) are looked at; ``tls://`` and the
other transports are left to ``distributed``.
"""

from __future__ import annotations

import socket
import struct
import time
from typing import Any

from bench.errors import RigError

#: the most bytes a handshake may take (a scheduler's is about 60)
MAX_HANDSHAKE_BYTES = 64 * 1024
#: the most frames it may claim (a scheduler's has one)
MAX_FRAMES = 16
#: the keys every Dask handshake holds (``distributed.comm.core.Comm.handshake_info``)
HANDSHAKE_KEYS = ("compression", "python", "pickle-protocol")
_U64 = struct.Struct("<Q")


class NotAScheduler(RigError):
    """``--scheduler`` names something that is not a Dask scheduler (one line, exit 2)."""


def probe(address: str, timeout_s: float) -> None:
    """Return if a Dask scheduler's handshake arrives from ``address`` within
    ``timeout_s`` seconds (connect included); else ``NotAScheduler`` saying what came."""
    scheme, _, loc = address.rpartition("://")
    if scheme not in ("", "tcp"):
        return
    host, port = _host_port(loc, address)
    deadline = time.monotonic() + timeout_s
    where = f"--scheduler {address}"
    try:
        with socket.create_connection((host, port), timeout=timeout_s) as sock:
            frames = _read_message(sock, deadline, where)
    except TimeoutError:
        raise NotAScheduler(f"{where}: no Dask handshake within {timeout_s:g} s (something "
                            "else listens there, e.g. a web server or the dashboard)") from None
    except OSError as exc:
        raise NotAScheduler(f"{where}: cannot reach a Dask scheduler there "
                            f"({exc.strerror or exc})") from None
    _check_handshake(frames, where)


def _host_port(loc: str, address: str) -> tuple[str, int]:
    host, sep, port = loc.rpartition(":")
    if not sep or not port.isdigit() or not host:
        raise NotAScheduler(f"--scheduler {address}: expected tcp://HOST:PORT")
    return host.strip("[]"), int(port)


def _read_message(sock: socket.socket, deadline: float, where: str) -> list[bytes]:
    """The frames of one Dask TCP message (``distributed.comm.tcp``: the length of a
    first block, which holds the frame count, each frame's length and the first frames;
    the other frames follow it), every length bounded before it is read."""
    (total,) = _U64.unpack(_read(sock, _U64.size, deadline))
    if total > MAX_HANDSHAKE_BYTES:
        raise NotAScheduler(f"{where}: not a Dask scheduler (its first message claims "
                            f"{total} bytes; a handshake is under {MAX_HANDSHAKE_BYTES})")
    body = _read(sock, total, deadline)
    count = _U64.unpack_from(body)[0] if total >= _U64.size else 0
    prelude = _U64.size * (count + 1)
    if not 1 <= count <= MAX_FRAMES or prelude > total:
        raise NotAScheduler(f"{where}: not a Dask scheduler (its first message is not "
                            "Dask's framing)")
    lengths = struct.unpack_from(f"<{count}Q", body, _U64.size)
    size = prelude + sum(lengths)
    if size > MAX_HANDSHAKE_BYTES:
        raise NotAScheduler(f"{where}: not a Dask scheduler (its first message claims "
                            f"{size} bytes; a handshake is under {MAX_HANDSHAKE_BYTES})")
    whole = body + _read(sock, max(0, size - total), deadline)
    starts = [prelude + sum(lengths[:i]) for i in range(count)]
    return [whole[at:at + n] for at, n in zip(starts, lengths, strict=True)]


def _read(sock: socket.socket, n: int, deadline: float) -> bytes:
    """Exactly ``n`` bytes before ``deadline`` (TimeoutError after it)."""
    data = bytearray()
    while len(data) < n:
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError
        sock.settimeout(left)
        got = sock.recv(n - len(data))
        if not got:
            raise ConnectionResetError(0, "the connection closed before a Dask handshake")
        data += got
    return bytes(data)


def _check_handshake(frames: list[bytes], where: str) -> None:
    """The frames decode (as ``distributed`` decodes them) to a handshake map."""
    from distributed.protocol.core import loads

    try:
        message: Any = loads(frames, deserialize=False)
    except Exception:  # any decoding failure means the same: not Dask's bytes
        message = None
    if not (isinstance(message, dict) and all(k in message for k in HANDSHAKE_KEYS)):
        raise NotAScheduler(f"{where}: not a Dask scheduler (its first message is no Dask "
                            "handshake)")
