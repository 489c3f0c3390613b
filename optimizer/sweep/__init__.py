"""Closed-loop design sweeps: every design ``optimize`` would consider, flown.

Pure, like the rest of ``optimizer``: which designs (``designs``), their stable ids and
seeds (``keys``), the per-design flight parameters as plain numbers (``flight_params``),
the rows and columns of the output (``rows``), one chunk of designs flown (``fly_rows``),
the chunking (``chunks``), the sweep's description for resume (``spec``) and the time
constant ranking built from the rows (``ranking``). Executors, Parquet parts, resume and
the progress bar live in ``bench.jobs.sweep_run`` and ``bench.jobs.sweep_parts``.
"""
