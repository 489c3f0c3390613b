"""``--scheduler`` at something that is not a Dask scheduler (``bench.jobs.sweep_scheduler``):
a web server or a server of other bytes, real ones on loopback, is one line within
seconds; a real scheduler's handshake passes."""

from __future__ import annotations

import contextlib
import http.server
import random
import socketserver
import threading
import time
from collections.abc import Iterator

import pytest
from rotorbench_tests_services import DaskCluster

from bench.jobs.sweep_scheduler import NotAScheduler, probe
from tests.bench.jobs.conftest import SWEEP, run_cli, unprofiled_cluster

pytestmark = pytest.mark.slow(wall_s=15)  # each CLI run waits out the probe's 4 s at most

#: the bytes the other server sends: fixed, so its first 8 bytes claim the same length
NOISE = random.Random(0).randbytes(4096)


class _Noise(socketserver.BaseRequestHandler):
    """Sends NOISE, then keeps the connection open until the client goes."""

    def handle(self) -> None:
        self.request.sendall(NOISE)
        with contextlib.suppress(OSError):
            self.request.settimeout(30)
            while self.request.recv(65536):
                pass


class _QuietHTTP(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args: object) -> None:  # no access log in the test output
        pass


@contextlib.contextmanager
def serving(server: socketserver.TCPServer) -> Iterator[str]:
    """``server`` (bound to 127.0.0.1:0) in a thread; its ``tcp://`` address."""
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        host, port = server.server_address[:2]
        yield f"tcp://{host}:{port}"
    finally:
        server.shutdown()
        server.server_close()


def _http() -> socketserver.TCPServer:
    return http.server.ThreadingHTTPServer(("127.0.0.1", 0), _QuietHTTP)


def _noise() -> socketserver.TCPServer:
    server = socketserver.ThreadingTCPServer(("127.0.0.1", 0), _Noise)
    server.daemon_threads = True
    return server


@pytest.mark.parametrize("make, words", [
    (_http, "no Dask handshake within 4 s"),
    (_noise, "not a Dask scheduler (its first message claims"),
])
def test_not_a_scheduler_is_one_line_within_seconds(tmp_path, make, words) -> None:
    """The command as typed, against a real server on loopback: exit 2, one line naming
    the address, no traceback, nothing written, in seconds (was a hang of minutes, or
    a try to allocate exabytes)."""
    with serving(make()) as address:
        start = time.monotonic()
        done = run_cli([*SWEEP, "--scheduler", address, "--out",
                        str(tmp_path / "s.parquet")], timeout_s=60)
        seconds = time.monotonic() - start
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().count("\n") == 0, done.stderr
    assert done.stderr.startswith(f"rotorbench: error: --scheduler {address}: {words}")
    assert seconds < 30  # start-up and planning included; the probe itself waits 4 s
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("make", [_http, _noise])
def test_the_probe_is_bounded_in_time(make) -> None:
    with serving(make()) as address:
        start = time.monotonic()
        with pytest.raises(NotAScheduler):
            probe(address, timeout_s=1.0)
        assert time.monotonic() - start < 3.0


def test_a_closed_port_is_unreachable() -> None:
    server = _http()
    address = f"tcp://127.0.0.1:{server.server_address[1]}"
    server.server_close()  # nothing listens there now
    with pytest.raises(NotAScheduler, match="cannot reach a Dask scheduler there"):
        probe(address, timeout_s=1.0)


@pytest.fixture(scope="module")
def scheduler() -> Iterator[DaskCluster]:
    """A real ``dask scheduler`` alone: the handshake is the scheduler's, no worker takes
    part in it (two would cost seconds of CPU to start, and heartbeats)."""
    with unprofiled_cluster(workers=0) as cluster:
        yield cluster


def test_a_real_schedulers_handshake_passes(scheduler) -> None:
    probe(scheduler.address, timeout_s=4.0)
