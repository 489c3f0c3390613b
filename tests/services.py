"""Real services for the tests: a throwaway PostgreSQL cluster, moto's S3 server and a
Dask cluster.

No mocks: the cluster is started from the machine's PostgreSQL binaries
(``/usr/lib/postgresql/*/bin``) on a free loopback port, as the ``postgres`` user when the
tests run as root (PostgreSQL refuses root), ``moto_server`` is a real HTTP S3
endpoint on 127.0.0.1, and ``dask scheduler`` / ``dask worker`` are the venv's own
processes on loopback ports. When one is missing, a laptop skips with one line; CI
(``CI=true``) fails, since ``.ci/run`` installs them.
"""

from __future__ import annotations

import contextlib
import glob
import importlib.util
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

SUPERUSER_PASSWORD = "s3cret-superuser-pw"


def missing(what: str) -> None:
    """Skip on a laptop, fail in CI, with one line."""
    msg = f"{what} (install it; .ci/run does)"
    if os.environ.get("CI"):
        pytest.fail(msg, pytrace=False)
    pytest.skip(msg)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_port(port: int, timeout_s: float) -> bool:
    """True once something listens on 127.0.0.1:``port``, False after ``timeout_s``."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), 0.2):
            return True
        time.sleep(0.05)
    return False


@dataclass
class Postgres:
    """A running cluster: ``url(user, password, db)`` builds a loopback URL."""

    port: int
    data: Path
    bindir: Path
    as_user: list[str]

    def url(self, user: str = "postgres", password: str | None = SUPERUSER_PASSWORD,
            db: str = "postgres") -> str:
        auth = f"{user}:{password}" if password is not None else user
        return f"postgresql://{auth}@127.0.0.1:{self.port}/{db}"

    def stop(self) -> None:
        subprocess.run([*self.as_user, str(self.bindir / "pg_ctl"), "-D", str(self.data),
                        "-m", "immediate", "stop"], capture_output=True, timeout=60)

    def start(self) -> None:
        subprocess.run([*self.as_user, str(self.bindir / "pg_ctl"), "-D", str(self.data),
                        "-l", str(self.data.parent / "log"), "-w", "-t", "60", "start"],
                       check=True, capture_output=True, timeout=90)


def pg_bindir() -> Path | None:
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"))
    env = shutil.which("initdb")
    if found:
        return Path(found[-1]).parent
    return Path(env).parent if env else None


@contextlib.contextmanager
def postgres_cluster() -> Iterator[Postgres]:
    """initdb + pg_ctl start on a free port; password (scram) on TCP, removed at the end."""
    bindir = pg_bindir()
    if bindir is None:
        missing("PostgreSQL server binaries not found (apt-get install postgresql)")
    as_user: list[str] = []
    if os.geteuid() == 0:
        if shutil.which("runuser") is None:
            missing("runuser not found: cannot start PostgreSQL as a non-root user")
        as_user = ["runuser", "-u", "postgres", "--"]
    root = Path(tempfile.mkdtemp(prefix="rotorbench-pg-"))
    try:
        if as_user:
            shutil.chown(root, "postgres")
        pw = root / "pw"
        pw.write_text(SUPERUSER_PASSWORD + "\n")
        if as_user:
            shutil.chown(pw, "postgres")
        port = free_port()
        subprocess.run([*as_user, str(bindir / "initdb"), "-D", str(root / "data"), "-U",
                        "postgres", "--pwfile", str(pw), "--auth-host=scram-sha-256",
                        "--auth-local=trust", "-E", "UTF8", "--no-sync"],
                       check=True, capture_output=True, timeout=120)
        conf = root / "data" / "postgresql.conf"
        with open(conf, "a") as fh:
            fh.write(f"\nport = {port}\nlisten_addresses = '127.0.0.1'\n"
                     f"unix_socket_directories = '{root}'\nfsync = off\n"
                     "synchronous_commit = off\nfull_page_writes = off\n")
        pg = Postgres(port, root / "data", bindir, as_user)
        pg.start()
        yield pg
        pg.stop()
    finally:
        shutil.rmtree(root, ignore_errors=True)


@dataclass
class S3Server:
    """A running ``moto_server``; ``env`` holds the AWS variables that reach it."""

    port: int
    proc: subprocess.Popen[bytes]

    @property
    def endpoint(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    @property
    def env(self) -> dict[str, str]:
        return {"AWS_ACCESS_KEY_ID": "lab-key", "AWS_SECRET_ACCESS_KEY": "lab-secret-key",
                "AWS_DEFAULT_REGION": "us-east-1", "AWS_REGION": "us-east-1",
                "AWS_ENDPOINT_URL": self.endpoint, "AWS_EC2_METADATA_DISABLED": "true"}

    def create_bucket(self, name: str) -> None:
        import urllib.request

        req = urllib.request.Request(f"{self.endpoint}/{name}", method="PUT")
        urllib.request.urlopen(req, timeout=10).close()

    def stop(self) -> None:
        self.proc.terminate()
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.proc.wait(10)
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)


def moto_command() -> list[str] | None:
    exe = Path(sys.executable).with_name("moto_server")
    if exe.exists():
        return [str(exe)]
    found = shutil.which("moto_server")
    return [found] if found else None


@contextlib.contextmanager
def s3_server(port: int | None = None) -> Iterator[S3Server]:
    cmd = moto_command()
    if cmd is None:
        missing("moto_server not found (pip install 'moto[server]')")
    port = port or free_port()
    proc = subprocess.Popen([*cmd, "-H", "127.0.0.1", "-p", str(port)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    server = S3Server(port, proc)
    try:
        if not wait_port(port, 30):
            pytest.fail("moto_server did not listen within 30 s", pytrace=False)
        yield server
    finally:
        server.stop()


@dataclass
class DaskCluster:
    """A running ``dask scheduler`` and its ``dask worker`` processes (no nanny: a worker
    killed is gone, as a lost machine is)."""

    port: int
    scheduler: subprocess.Popen[bytes]
    workers: list[subprocess.Popen[bytes]]
    folder: Path

    @property
    def address(self) -> str:
        return f"tcp://127.0.0.1:{self.port}"

    def add_worker(self, name: str) -> subprocess.Popen[bytes]:
        """Start one more single-thread worker; returns once the scheduler has it."""
        proc = subprocess.Popen(
            [*dask_command(), "worker", self.address, "--nthreads", "1", "--no-dashboard",
             "--no-nanny", "--host", "127.0.0.1", "--name", name, "--memory-limit", "0",
             "--death-timeout", "60", "--local-directory", str(self.folder / name)],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.workers.append(proc)
        if not self.wait_workers(sum(w.poll() is None for w in self.workers), 60):
            pytest.fail(f"dask worker {name} did not join {self.address} within 60 s",
                        pytrace=False)
        return proc

    def wait_workers(self, count: int, timeout_s: float) -> bool:
        """True once the scheduler lists exactly ``count`` workers."""
        from distributed import Client

        end = time.monotonic() + timeout_s
        with Client(self.address, timeout="10s", set_as_default=False) as client:
            while time.monotonic() < end:
                if len(client.scheduler_info(n_workers=-1)["workers"]) == count:
                    return True
                time.sleep(0.1)
        return False

    def stop(self) -> None:
        """Workers first (a worker whose scheduler went first retries to reach it), then
        the scheduler; whatever has not ended within 5 s is killed."""
        for group in (self.workers, [self.scheduler]):
            for proc in group:
                if proc.poll() is None:
                    proc.terminate()
            deadline = time.monotonic() + 5.0
            for proc in group:
                try:
                    proc.wait(max(0.0, deadline - time.monotonic()))
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait(10)


def dask_command() -> list[str]:
    """The venv's ``dask`` command (the sweep extra installs it)."""
    exe = Path(sys.executable).with_name("dask")
    if not exe.exists() or importlib.util.find_spec("distributed") is None:
        missing("dask[distributed] not installed (pip install 'rotorbench[sweep]')")
    return [str(exe)]


@contextlib.contextmanager
def dask_cluster(workers: int = 2) -> Iterator[DaskCluster]:
    """A ``dask scheduler`` on a free loopback port and ``workers`` single-thread
    workers; every process is terminated at the end, whatever happened."""
    cmd = dask_command()
    port = free_port()
    folder = Path(tempfile.mkdtemp(prefix="rotorbench-dask-"))
    scheduler = subprocess.Popen(
        [*cmd, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard",
         "--dashboard-address", "127.0.0.1:0"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=folder)
    cluster = DaskCluster(port, scheduler, [], folder)
    try:
        if not wait_port(port, 60):
            pytest.fail("dask scheduler did not listen within 60 s", pytrace=False)
        for i in range(workers):
            cluster.add_worker(f"w{i}")
        yield cluster
    finally:
        cluster.stop()
        shutil.rmtree(folder, ignore_errors=True)


# -- fixtures (the root conftest loads this module, so every folder shares one cluster) ---
_count = __import__("itertools").count()


@pytest.fixture(scope="session")
def pg_cluster() -> Iterator[Postgres]:
    """One PostgreSQL cluster per test session (per xdist worker)."""
    with postgres_cluster() as pg:
        yield pg


@pytest.fixture
def pg_url(pg_cluster: Postgres) -> str:
    """A superuser URL of a new empty database."""
    import psycopg

    name = f"lab_{os.getpid()}_{next(_count)}"
    with psycopg.connect(pg_cluster.url(), autocommit=True) as con:
        con.execute(f"DROP DATABASE IF EXISTS {name}")
        con.execute(f"CREATE DATABASE {name}")
    return pg_cluster.url(db=name)


@pytest.fixture(scope="session")
def s3() -> Iterator[S3Server]:
    with s3_server() as server:
        yield server


@pytest.fixture
def s3_env(s3: S3Server, monkeypatch: pytest.MonkeyPatch) -> S3Server:
    """The AWS_* variables of the S3 server set for this test, and a fresh bucket."""
    for k, v in s3.env.items():
        monkeypatch.setenv(k, v)
    bucket = f"lab{os.getpid()}x{next(_count)}"
    s3.create_bucket(bucket)
    s3.bucket = bucket  # type: ignore[attr-defined]
    return s3
