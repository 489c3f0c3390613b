"""argparse helpers the commands share (commands never import each other): one module a
concern: what the user gave, the run arguments, the sizing options, the store options."""
