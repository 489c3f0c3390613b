"""A run on the wall clock runs ahead of the machine's other work, behind the devices.

Why: the command loop of a run on the wall clock (a real rig, the firmware, a paced
simulated bench) must check in with the watchdog every tick; on a busy machine (a build,
a browser, other test processes) the scheduler may let it wait half a second, the watchdog
then stops the motor and the run is lost for a reason that has nothing to do with the
bench. Every thread of the process is raised, not the loop's alone: the loop waits for
the interpreter lock, which a window's or a reader's thread may hold, and a holder left
waiting for a core would stall the loop as surely. The level sits between the default
and the devices' (``drivers.device_priority``): the stand-ins of device firmware still
answer first. A run on a simulated clock runs flat out and is not raised. Raising needs
the privilege (root, or CAP_SYS_NICE); without it the run keeps the default share. At
the last run's end every thread goes back to the niceness the process had.

Niceness orders threads inside one scheduling group only; where Linux groups each
session's processes (autogroup), a bench that leads a session of its own (started by a
service manager, ``setsid``, a test) is raised as a group too, at the same level, and
handed back at the end. A bench typed in a terminal shares the terminal's session and its
group is left alone: it is not the bench's (``drivers.device_priority``).
"""

from __future__ import annotations

import os
from typing import ClassVar

from bench.engine.process_wide import ProcessWide
from drivers.device_priority import (
    DEVICE_NICE,
    process_threads,
    session_group_nice,
    set_session_group,
)

__all__ = ["HOST_LOOP_NICE", "HostPriority"]

HOST_LOOP_NICE = DEVICE_NICE // 2  # ahead of the default (0), behind the devices


class HostPriority(ProcessWide):
    """``with HostPriority(on_wall):`` raises this process's threads for the block when
    ``on_wall``; runs in threads of one process may overlap (the last one restores)."""

    _before: ClassVar[dict[int, int]]
    _group_before: ClassVar[int | None]

    def __init__(self, on_wall: bool) -> None:
        self.active = on_wall

    def _begin(self) -> None:
        HostPriority._before = _raise_threads(HOST_LOOP_NICE)
        HostPriority._group_before = _raise_own_group(HOST_LOOP_NICE)

    def _end(self) -> None:
        _restore_threads(HostPriority._before)
        if HostPriority._group_before is not None:
            set_session_group(os.getpid(), HostPriority._group_before)


def _raise_own_group(nice: int) -> int | None:
    """The niceness of this process's session group before, if this process leads its
    session and raised it (module doc); else None."""
    pid = os.getpid()
    was = session_group_nice(pid)
    if was is None or was <= nice or os.getsid(0) != pid:
        return None
    return was if set_session_group(pid, nice) else None


def _raise_threads(nice: int) -> dict[int, int]:
    """Each thread's niceness before, for those raised (none without the privilege)."""
    before: dict[int, int] = {}
    for tid in process_threads(os.getpid()):
        try:
            was = os.getpriority(os.PRIO_PROCESS, tid)
            if was > nice:
                os.setpriority(os.PRIO_PROCESS, tid, nice)
                before[tid] = was
        except OSError:  # no privilege, or the thread ended meanwhile
            continue
    return before


def _restore_threads(before: dict[int, int]) -> None:
    """Threads raised go back; threads started meanwhile (they inherited the raise) go to
    the process's own niceness from before."""
    if not before:
        return
    base = before.get(os.getpid(), max(before.values()))
    for tid in process_threads(os.getpid()):
        try:
            if os.getpriority(os.PRIO_PROCESS, tid) == HOST_LOOP_NICE:
                os.setpriority(os.PRIO_PROCESS, tid, before.get(tid, base))
        except OSError:
            continue
