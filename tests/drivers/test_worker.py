"""The background worker (``drivers.worker``): calls run in turn, results come back in
order, an exception is raised in the caller, and the thread ends when idle."""

from __future__ import annotations

import threading
import time

import pytest

from drivers.worker import Worker


def test_results_in_order_and_errors_raised_in_the_caller() -> None:
    w = Worker("test-worker")
    seen: list[str] = []
    w.submit(lambda x: seen.append(threading.current_thread().name) or x * 2, 21)
    w.submit(lambda: 1 / 0)
    w.submit(str.upper, "ok")
    assert w.pending == 3
    assert w.result() == 42
    with pytest.raises(ZeroDivisionError):
        w.result()
    assert w.result() == "OK"
    assert seen == ["test-worker"] and w.pending == 0
    with pytest.raises(RuntimeError, match="no call to collect"):
        w.result()


def test_the_thread_ends_when_idle_and_comes_back_for_the_next_call() -> None:
    w = Worker("test-idle", idle_s=0.05)
    w.submit(int, "1")
    assert w.result() == 1
    deadline = time.monotonic() + 5.0
    while w._thread is not None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert w._thread is None
    assert not any(t.name == "test-idle" for t in threading.enumerate())
    w.submit(int, "2")
    assert w.result() == 2
