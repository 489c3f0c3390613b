"""One module per CLI subcommand.

Each module defines ``register(subparsers)`` which adds its parser and sets
``func=handler`` via ``set_defaults``; ``handler(args) -> int`` returns the exit code.
The CLI discovers modules here, so adding a command never touches a shared file.
"""
