"""Protocol codecs: pure functions from bytes to messages and back.

One module per protocol (``msp``, ``gx3``, ``vesc_can``, ``dronecan``, ``gcs``,
``loadcell_lines``); ``stream`` holds the common incremental decoder shape (feed bytes,
get messages, counters of what was dropped), ``can_log`` CAN frames as plain data and
candump-style logs, ``transcript`` the hex-dump files of ``fixtures/transcripts``.
No module here opens a port or imports a vendor library; backends do that.
"""
