"""A CAN link over a loopback stream socket: the simulated CAN nodes' cable to the host.

Why: python-can's ``virtual`` bus lives inside one process, and the simulated nodes run in
a process of their own (``drivers.wire_sim.world_process``). The world's nodes talk to a
:class:`SocketCanLink`; on the host's side another one is relayed to the peers' end of the
rig's ``virtual`` channel (:func:`relay`), so the host's backends open a python-can bus as
on a bench. Frames queue in the socket while a reader is late, as in an adapter's buffer.
"""

from __future__ import annotations

import contextlib
import socket
import struct
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from drivers.codecs.can_log import CanFrame
from drivers.errors import DeviceError

if TYPE_CHECKING:
    from drivers.wire_sim.world_process import Remote

__all__ = ["SocketCanLink", "bridge", "cabled_node", "node_process", "relay"]

_HEADER = struct.Struct("<I?B")  # arbitration id, extended id, data length


class SocketCanLink:
    """``CanLink``'s face (subscribe, send, close) on a connected stream socket."""

    def __init__(self, sock: socket.socket, name: str) -> None:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.sock = sock
        self.name = name
        self._subs: list[Callable[[CanFrame], None]] = []
        self._lock = threading.Lock()
        self._send_lock = threading.Lock()
        self._closed = False
        self._thread = threading.Thread(target=self._run, name=f"can-socket {name}",
                                        daemon=True)
        self._thread.start()

    def subscribe(self, callback: Callable[[CanFrame], None]) -> None:
        with self._lock:
            self._subs.append(callback)

    def unsubscribe(self, callback: Callable[[CanFrame], None]) -> None:
        with self._lock:
            if callback in self._subs:
                self._subs.remove(callback)

    def send(self, frame: CanFrame) -> None:
        if self._closed:
            raise DeviceError(f"{self.name}: link is closed")
        data = bytes(frame.data)
        try:
            with self._send_lock:
                self.sock.sendall(_HEADER.pack(frame.arbitration_id, frame.is_extended_id,
                                               len(data)) + data)
        except OSError as exc:
            raise DeviceError(f"{self.name}: CAN send failed ({exc})") from None

    def _run(self) -> None:
        with contextlib.suppress(OSError), self.sock.makefile("rb") as stream:
            while (head := stream.read(_HEADER.size)) and len(head) == _HEADER.size:
                ident, extended, size = _HEADER.unpack(head)
                frame = CanFrame(ident, stream.read(size), extended)
                with self._lock:
                    subs = list(self._subs)
                for cb in subs:
                    with contextlib.suppress(DeviceError):  # a closed far end: the cable is out
                        cb(frame)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            with contextlib.suppress(OSError):
                self.sock.shutdown(socket.SHUT_RDWR)
            self.sock.close()
            if self._thread is not threading.current_thread():
                self._thread.join(timeout=1.0)


def relay(a: Any, b: Any) -> Callable[[], None]:
    """Every frame heard on link ``a`` is sent on ``b`` and back (both CanLink-like);
    returns the undo. A frame for a link already closed is dropped, as a cable pulled out
    drops it: a bus's reader thread may be handing one over as the other end closes."""

    def to(link: Any) -> Callable[[CanFrame], None]:
        def send(frame: CanFrame) -> None:
            with contextlib.suppress(DeviceError):
                link.send(frame)
        return send

    to_b, to_a = to(b), to(a)
    a.subscribe(to_b)
    b.subscribe(to_a)

    def undo() -> None:
        a.unsubscribe(to_b)
        b.unsubscribe(to_a)

    return undo


def bridge(link: Any, connect: Callable[[int], object],
           name: str) -> tuple[SocketCanLink, Callable[[], None]]:
    """Joins ``link`` (the nodes' end of a host's bus) to nodes in another process:
    ``connect(port)`` has them connect to a loopback listener on ``port``; frames are
    relayed both ways. Returns the host's socket link and the stop (relay undone, socket
    closed)."""
    with socket.create_server(("127.0.0.1", 0)) as server:
        server.settimeout(10.0)
        connect(server.getsockname()[1])
        conn, _ = server.accept()
    conn.settimeout(None)
    far = SocketCanLink(conn, name)
    undo = relay(link, far)

    def stop() -> None:
        undo()
        far.close()

    return far, stop


def node_process(link: Any, make: Callable[..., Any], settings: dict[str, Any],
                 name: str) -> tuple[Remote, Callable[[], None]]:
    """A simulated CAN node in a process of its own, as a device's firmware runs on its own
    processor, on a cable to ``link`` (the nodes' end of a host's bus): ``make(cable,
    **settings)`` there (e.g. ``SimVescDevice``), its cable a :class:`SocketCanLink` to a
    loopback listener here. Returns the node there (a ``Remote``: ``node.get("command")``)
    and the stop (cable out, process ended)."""
    from drivers.wire_sim.world_process import WorldProcess, one_device

    worlds: list[WorldProcess] = []
    _, unplug = bridge(link, lambda port: worlds.append(WorldProcess(
        one_device, cabled_node, {"make": make, "port": port, "name": name, **settings},
        name=name)), f"{name} cable")

    def stop() -> None:
        unplug()
        worlds[0].close()

    return worlds[0].remote("device"), stop


def cabled_node(make: Callable[..., Any], port: int, name: str, **settings: Any) -> Any:
    """``make(cable, **settings)`` on a cable to loopback ``port`` (the node's process's
    side of :func:`node_process`)."""
    return make(SocketCanLink(socket.create_connection(("127.0.0.1", port)),
                              f"{name} cable"), **settings)
