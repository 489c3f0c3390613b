"""``rotorbench serve``: the read-only web view of a store (runs, one run, compare, constants)."""
