"""Fits and calibrations on run records; never imports drivers or bench."""
