"""Input paths the commands read, checked before they are read.

Two inputs turn a plain read into a fault: a path that is not a regular file (``/dev/zero``
or a tty reads forever and fills the memory, a FIFO blocks until a writer comes) and a
symbolic-link loop (``Path.resolve`` raises RuntimeError on Python 3.11, ``exists`` says
False, so the user reads "not found" for a file they can see). Both are refused in one
line (exit 2) naming the option and the path. A missing path or a folder where a file is
wanted is left to the reader, whose message says what it expected.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from bench.errors import RigError

__all__ = ["check_input", "refuse_loop"]

_KINDS = ((stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISSOCK, "a socket"))


def refuse_loop(path: Path, where: str, point_at: str = "a file") -> int | None:
    """``path``'s mode (None if missing or unreadable), or RigError naming ``where`` if it
    is a loop of symbolic links; ``point_at`` says what the link should name."""
    try:
        return os.stat(path).st_mode
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise RigError(f"{where}: a loop of symbolic links (a link that points back "
                           f"at itself); point it at {point_at}") from None
        return None


def check_input(path: str | os.PathLike[str], flag: str = "") -> Path:
    """``path`` unchanged, or RigError if it is a symlink loop or not a regular file or
    folder; ``flag`` (``--rig``) prefixes the message."""
    path = Path(path)
    where = f"{flag} {path}" if flag else str(path)
    mode = refuse_loop(path, where)
    if mode is None:
        return path  # missing or unreadable: the reader names what it expected
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return path
    kind = next((name for test, name in _KINDS if test(mode)), "not a regular file")
    raise RigError(f"{where}: is {kind}, not a regular file; save the data to a file "
                   "and give that")
