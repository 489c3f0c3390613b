"""The safe run loop and its parts (limits, watchdog, drops, recorder); no plans."""
