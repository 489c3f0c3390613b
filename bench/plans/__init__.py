"""Plans as data: sequences, plan specs, calibration sequences, budget, thrust map."""
