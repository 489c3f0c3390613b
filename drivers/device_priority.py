"""A device's process scheduled ahead of the host's work, as if on a processor of its own.

Why: a real device's firmware runs on its own processor, so it answers on time whatever
the host does. Its stand-ins here (a simulated device world, the Betaflight SITL) share the
host's cores; on a loaded machine the scheduler would let them wait behind the host's and
the machine's other work, and they would answer late for reasons no real device has. They
sleep between frames and take little time, so running them first costs the rest little.
Linux niceness is per thread: every thread the process has when raised, and every thread
it starts later (which inherits it), runs at ``DEVICE_NICE``.

A device's timers are exact too: each thread's timer slack goes from Linux's default 50 us
to ``DEVICE_TIMER_SLACK_NS``. The Betaflight SITL's main loop sleeps 50 us between
scheduler passes; with the default slack a pass comes every 60-110 us, which beats against
its 125 us gyro period, and its low-rate tasks starve: measured over 4 s on an idle
machine, the serial task ran at 24-62 Hz of its 100 (MSP replies up to 1.2 s late, the
receiver's 150 ms loss tripped while the host sent on time) and the accelerometer at
41-276 Hz of its 1000; with 1 us slack at 96-97 Hz and 834-910 Hz, the gyro and PID at
their 8 and 4 kHz, MSP replies within 21 ms.

Niceness only orders threads of one scheduling group. Where Linux groups each session's
processes (autogroup, on by default in desktop and server kernels), a session's group
shares the cores equally with every other session's, whatever its threads' niceness: a
device stand-in in the test suite's session ran at -10 inside that one group, against the
whole suite, while a browser, a database or a Dask worker in a session of its own each had
a group's share. So a stand-in is started in a session of its own (``start_new_session``)
and its session's group is raised too (``/proc/PID/autogroup``, sched(7)): measured here,
a thread that needs about 85 % of a core while 3 busy processes share its session and 3
more run in sessions of their own made 3 800 passes in 4 s in the shared session (its p99
pass 7.7 ms late) and 9 500 in its own raised session (p99 0.08 ms).

Both need the privilege (root, or CAP_SYS_NICE); without it the process keeps the default
share and slack.
"""

from __future__ import annotations

import os
import threading

__all__ = ["DEVICE_NICE", "DEVICE_TIMER_SLACK_NS", "process_threads", "raise_device_priority",
           "session_group_nice", "set_session_group"]

DEVICE_NICE = -10
DEVICE_TIMER_SLACK_NS = 1000


def process_threads(pid: int) -> list[int]:
    """The thread ids of process ``pid`` (just ``pid`` where /proc cannot tell)."""
    try:
        return [int(t) for t in os.listdir(f"/proc/{pid}/task")]
    except OSError:  # no /proc (not Linux), or the process is gone
        return [pid]


def session_group_nice(pid: int) -> int | None:
    """The niceness of the scheduling group of ``pid``'s session (autogroup), or None where
    the kernel has none."""
    try:
        with open(f"/proc/{pid}/autogroup") as group:  # "/autogroup-25 nice 0"
            return int(group.read().split()[-1])
    except (OSError, ValueError, IndexError):
        return None


def raise_device_priority(pid: int = 0) -> bool:
    """Run process ``pid`` (0: this one, from its calling thread on) at ``DEVICE_NICE``
    with ``DEVICE_TIMER_SLACK_NS``, and its session's scheduling group at ``DEVICE_NICE``
    when it leads a session of its own (module doc); whether it could."""
    tasks = [threading.get_native_id()] if pid == 0 else process_threads(pid)
    ok = set_session_group(pid or os.getpid(), DEVICE_NICE)
    for tid in tasks:
        try:
            os.setpriority(os.PRIO_PROCESS, tid, DEVICE_NICE)
            with open(f"/proc/{tid}/timerslack_ns", "w") as slack:
                slack.write(str(DEVICE_TIMER_SLACK_NS))
        except OSError:  # no privilege, no /proc, or the thread ended meanwhile
            ok = False
    return ok


def set_session_group(pid: int, nice: int) -> bool:
    """Set the scheduling group of ``pid``'s session to ``nice``, only when ``pid`` leads
    that session: another's group (the terminal's, the test suite's) is not the process's
    to change. True where there is nothing to raise."""
    try:
        if os.getsid(pid) != pid:
            return True
        with open(f"/proc/{pid}/autogroup", "w") as group:
            group.write(str(nice))
    except FileNotFoundError:  # a kernel without autogroup, or the process ended meanwhile
        return os.path.isdir(f"/proc/{pid}")
    except OSError:  # no privilege, or the process ended meanwhile
        return False
    return True
