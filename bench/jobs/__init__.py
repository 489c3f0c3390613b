"""Whole jobs: a plan run with progress, all calibration stages, the map sweep."""
