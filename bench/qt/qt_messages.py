"""Qt's own messages, minus the one the offscreen platform repeats on every resize.

Qt's offscreen plugin (tests, the self-test, screenshots, a console started over SSH
with ``QT_QPA_PLATFORM=offscreen``) prints "This plugin does not support
propagateSizeHints()" each time a window's size hints change: a flood that hides real
warnings. The handler drops that one message and passes every other one on to the log
(``bench.qt.qt_messages``): a window process has no handler of its own, so Python's last
resort writes it to stderr as one line, as Qt would.
"""

from __future__ import annotations

import logging
from typing import Any

__all__ = ["DROPPED", "filter_qt_messages"]

#: Messages dropped (substrings): harmless, and repeated by the offscreen plugin.
DROPPED = ("does not support propagateSizeHints()",)

_installed = False
_log = logging.getLogger(__name__)


def _handler(_kind: Any, _context: Any, message: str) -> None:
    if any(d in message for d in DROPPED):
        return
    _log.warning(message)


def filter_qt_messages() -> None:
    """Install the filtering handler (once per process; before the first window)."""
    global _installed
    if _installed:
        return
    from pyqtgraph.Qt import QtCore

    QtCore.qInstallMessageHandler(_handler)
    _installed = True
