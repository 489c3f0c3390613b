"""Every check of a path a command reads or writes, in one room below all its users."""
