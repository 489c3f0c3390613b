"""The bench calibrating its own force sensors against known weights: the plan (which
weights, in which order, how long each is held), who puts them on (an operator prompted
step by step, or an automatic fixture), the recorded calibration run and its record."""
