"""The bench console: a desktop window that runs the stand by hand and by plan.

Two processes, as for the live view (:mod:`bench.live`): the bench process opens the rig,
runs the safe run loop (:class:`bench.plan_runner.runner.Runner`, its watchdog and limits)
and records every run; the window process only sends requests (arm, throttle, stop, start
a plan, tare, tighten a limit) and shows state. A window that closes, crashes or freezes
(no heartbeat within :data:`bench.console.link.HEARTBEAT_BOUND_S`) ends the run with the ESC idle
and disarmed. Only :mod:`bench.console.window`, :mod:`bench.console.tabs` and
:mod:`bench.console.gui_main` import Qt.
"""
