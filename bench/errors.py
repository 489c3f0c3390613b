"""User-facing errors of the bench (rig files, sequences, run folders)."""


class RigError(ValueError):
    """A rig file or sequence is invalid; the message names the file and field."""

    exit_code = 2


class ThrustOutsideMap(RigError):
    """A thrust setpoint beyond the measured range of a static thrust map; ``lo``/``hi``
    let the caller (a sequence) say which setpoint is wrong rather than blame the map."""

    def __init__(self, message: str, lo: float, hi: float) -> None:
        super().__init__(message)
        self.lo, self.hi = lo, hi


class RecordingError(RuntimeError):
    """A run folder could not be written (disk full, medium gone): the run is aborted.

    Raised by the recorder; the runner stops the actuators safely first, as for any error.
    """

    exit_code = 2
