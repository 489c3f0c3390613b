"""Simulated devices that speak the real wire protocols on real transports.

They answer on python-can's ``virtual`` bus, pseudo-terminals or loopback TCP with the
bytes a real device would send, so the real backends run end to end without hardware.
Their physics comes from a small model object passed in (the simulated plant, or a simple
stand-in), never from the transport.
"""
