"""The lab-store tests use the real services of tests/services.py (root conftest)."""

from __future__ import annotations

import contextlib
import io
import os
import subprocess

import pytest

from bench.cli import main


def as_environment(mp: pytest.MonkeyPatch, env: dict[str, str]) -> None:
    """This process's environment made ``env`` (undone with ``mp``): the one a
    ``rotorbench`` process of the test is given."""
    for k in set(os.environ) - set(env):
        mp.delenv(k)
    for k, v in env.items():
        if os.environ.get(k) != v:
            mp.setenv(k, v)


def cli_in_process(argv: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    """``rotorbench ARGV`` run in this process with ``env`` as its whole environment: the
    exit code and output a ``subprocess.run`` of it gives. For steps that test what a
    command says and does, not a process (a fresh interpreter each was most of these files'
    CPU); test_lab_secrets runs the commands as processes of their own."""
    with pytest.MonkeyPatch.context() as mp:
        as_environment(mp, env)
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(argv)
    return subprocess.CompletedProcess(argv, code, out.getvalue(), err.getvalue())
