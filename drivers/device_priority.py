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
    ok = _raise_own_autogroup(pid)
    for tid in tasks:
        try:
            os.setpriority(os.PRIO_PROCESS, tid, DEVICE_NICE)
        except OSError:  # no privilege, or the thread ended meanwhile
            ok = False
    return ok


def _raise_own_autogroup(pid: int) -> bool:
    """A process that leads a session of its own (started with ``setsid``, as the bench
    starts the firmware) is, where the kernel groups sessions (``autogroup``), scheduled as
    a group of its own against every other session: a thread's niceness only orders it
    inside its group, so the group's niceness is raised too. Nothing to do (True) for a
    process inside its parent's session, or where there are no autogroups."""
    target = os.getpid() if pid == 0 else pid
    try:
        if os.getsid(target) != target:
            return True
        with open(f"/proc/{target}/autogroup", "w") as fh:
            fh.write(str(DEVICE_NICE))
    except FileNotFoundError:  # no autogroups (kernel without them, not Linux)
        return True
    except OSError:  # no privilege, or the process is gone
        return False
    return True

