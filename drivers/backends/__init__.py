"""Backends on real transports: device contracts filled by a protocol codec over a port.

Each backend receives its transport from outside (a ``can.BusABC``, a ``serial.SerialBase``,
a socket); one module per vendor library imports it (``can_link`` for python-can).
"""
