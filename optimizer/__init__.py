"""Component catalogs, the multirotor design model and MILP design selection (Papers D, E)."""
