"""A device's process scheduled ahead of the host's work, as if on a processor of its own.

Why: a real device's firmware runs on its own processor, so it answers on time whatever
the host does. Its stand-ins here (a simulated device world, the Betaflight SITL) share the
host's cores; on a loaded machine the scheduler would let them wait behind the host's and
the machine's other work, and they would answer late for reasons no real device has. They
sleep between frames and take little time, so running them first costs the rest little.
Linux niceness is per thread: every thread the process has when raised, and every thread
it starts later (which inherits it), runs at ``DEVICE_NICE``. Raising needs the privilege
(root, or CAP_SYS_NICE); without it the process keeps the default share.
"""

from __future__ import annotations

import os

__all__ = ["DEVICE_NICE", "process_threads", "raise_device_priority"]

DEVICE_NICE = -10


def process_threads(pid: int) -> list[int]:
    """The thread ids of process ``pid`` (just ``pid`` where /proc cannot tell)."""
    try:
        return [int(t) for t in os.listdir(f"/proc/{pid}/task")]
    except OSError:  # no /proc (not Linux), or the process is gone
        return [pid]


def raise_device_priority(pid: int = 0) -> bool:
    """Run process ``pid`` (0: this one, from its calling thread on) at ``DEVICE_NICE``;
    whether it could."""
    tasks = [0] if pid == 0 else process_threads(pid)
    ok = True
    for tid in tasks:
        try:
            os.setpriority(os.PRIO_PROCESS, tid, DEVICE_NICE)
        except OSError:  # no privilege, or the thread ended meanwhile
            ok = False
    return ok
