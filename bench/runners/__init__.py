"""The one runner that walks a plan on the run loop, and the session recording it."""
