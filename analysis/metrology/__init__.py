"""Metrology of the bench's own sensors: reference forces from dead weights, the fit of a
calibration series, and GUM uncertainty budgets (JCGM 100) and comparisons (E_n).

Pure analysis: works on any series of (reference force, reading) pairs, from a guided
calibration on the bench or from a lab's own records.
"""
