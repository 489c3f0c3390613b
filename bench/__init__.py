"""The bench: sequences, runner, safety supervisor, recorder, rig files and the CLI."""
