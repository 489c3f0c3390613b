"""The registry entries of every protocol, one module per URL scheme.

Importing this package registers them all in ``drivers.registry`` (``drivers.device_context``
does): ``sim``/``replay`` (simulated and recorded devices), ``serial`` (MSP, VESC UART,
line-printing load-cell boards, GX3), ``can`` (VESC,
DroneCAN), ``nidaq`` (NI-DAQmx analog inputs, counters, pulse train), ``tcp`` (PI GCS
hexapod) and ``msp+tcp`` (a flight controller's MSP over TCP).
"""

from drivers.protocols import can, msp_tcp, nidaq, serial, sim, tcp

__all__ = ["can", "msp_tcp", "nidaq", "serial", "sim", "tcp"]
