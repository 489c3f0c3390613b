"""The plan runner: walks one plan on the engine and records it as one indexed run."""
