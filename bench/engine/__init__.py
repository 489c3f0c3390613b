"""The engine: the safe run loop and its parts (limits, watchdog, drops, recorder); it
knows no plan, rig or store."""
