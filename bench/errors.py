"""User-facing errors of the bench (rig files, sequences, run folders)."""


class RigError(ValueError):
    """A rig file or sequence is invalid; the message names the file and field."""

    exit_code = 2
