"""Qt plumbing shared by the windows (the live view and the console)."""
