"""User-facing device errors: bad bytes, timeouts, disconnects, bad URLs."""


class DeviceError(RuntimeError):
    """A device misbehaved or vanished; the message names the device and what happened."""

    exit_code = 2
