"""An install outside the clone works: the wheel built from the tracked files, installed
into a fresh venv, runs `demo`, `step`, `optimize`, `fly`, `serve` and `console --selftest`
from an empty folder, with the shipped rigs and catalogs found as package data."""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
#: what the wheel is built from (the packages and what pyproject.toml names)
SOURCES = ("pyproject.toml", "README.md", "LICENSE", "bench/", "drivers/", "analysis/",
           "optimizer/")


def _uv() -> str | None:
    beside = Path(sys.executable).parent / "uv"
    return str(beside) if beside.is_file() else shutil.which("uv")


def _copy_tracked_sources(dest: Path) -> None:
    """The tracked files the wheel is built from, so nothing untracked sneaks into it."""
    names = subprocess.run(["git", "ls-files", "-z", *SOURCES], cwd=REPO, check=True,
                           capture_output=True).stdout.decode().split("\0")
    for name in filter(None, names):
        target = dest / name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / name, target)


def _build_and_install(tmp: Path) -> Path:
    """Build the wheel and install it with the extras serve and console need; the venv's
    python."""
    src, dist, venv = tmp / "src", tmp / "dist", tmp / "venv"
    _copy_tracked_sources(src)
    uv = _uv()
    if uv:
        subprocess.run([uv, "build", "--wheel", "--quiet", "--out-dir", str(dist), str(src)],
                       check=True)
        subprocess.run([uv, "venv", "--quiet", "--python", sys.executable, str(venv)],
                       check=True)
    else:  # the Makefile's fallback: pip alone
        subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps",
                        "--wheel-dir", str(dist), str(src)], check=True)
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    (wheel,) = dist.glob("rotorbench-*.whl")
    python = venv / "bin" / "python"
    spec = f"rotorbench[live,serve] @ {wheel.as_uri()}"
    install = ([uv, "pip", "install", "--quiet", "--python", str(python), spec] if uv else
               [str(python), "-m", "pip", "install", "--quiet", spec])
    subprocess.run(install, check=True)
    return python


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if not k.startswith("ROTORBENCH_") and k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    return {**env, "QT_QPA_PLATFORM": "offscreen"}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _page(url: str, within_s: float) -> str:
    end = time.monotonic() + within_s
    while True:
        try:
            with urllib.request.urlopen(url, timeout=5) as reply:
                return reply.read().decode()
        except (urllib.error.URLError, ConnectionError):
            if time.monotonic() > end:
                raise
            time.sleep(0.2)


@pytest.mark.slow(wall_s=50)
def test_the_installed_wheel_runs_the_commands_outside_the_clone(tmp_path: Path) -> None:
    python = _build_and_install(tmp_path)
    rotorbench = python.parent / "rotorbench"
    work = tmp_path / "work"
    work.mkdir()

    def run(*argv: str) -> str:
        done = subprocess.run([str(rotorbench), *argv], cwd=work, env=_env(),
                              capture_output=True, text=True, timeout=300, check=False)
        assert done.returncode == 0, f"rotorbench {' '.join(argv)}: {done.stderr}"
        return done.stdout

    where = subprocess.run([str(python), "-c", "import bench, optimizer; "
                            "print(bench.__file__); print(optimizer.__file__)"],
                           cwd=work, env=_env(), capture_output=True, text=True, check=True)
    assert all(Path(p).is_relative_to(tmp_path / "venv") for p in where.stdout.split())

    assert "written in" in run("demo", "--combos", "1", "--repeats", "1", "--out", "demo")
    assert "success: sequence complete" in run("step", "--repeats", "1", "--out", "runs")
    catalog = Path(json.loads(run("optimize", "--payload-kg", "1.5", "--json"))["catalog"])
    assert catalog.is_relative_to(tmp_path / "venv")
    assert catalog.parts[-4:] == ("optimizer", "data", "catalogs", "thesis-e")
    assert "hover" in run("fly", "--actuators", "4", "--propeller", "P4", "--motor", "M1",
                          "--battery", "B3")
    # the window's frame-rate floor is the user's check of their machine; this one is loaded
    assert "selftest: ok" in run("console", "--selftest", "--out", "console", "--min-fps", "0")

    port = _free_port()
    server = subprocess.Popen([str(rotorbench), "serve", "--store", "runs", "--port",
                               str(port)], cwd=work, env=_env(),
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        page = _page(f"http://127.0.0.1:{port}/", within_s=60)
    finally:
        server.terminate()
        server.wait(timeout=30)
    (run_id,) = [p.name for p in (work / "runs").iterdir() if p.name.endswith("-step1")]
    assert run_id in page
