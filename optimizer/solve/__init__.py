"""Choosing designs: objectives, the exact MILP, enumeration, the thesis' own MILP, Pareto
fronts, series/parallel packs and the options a request adds.

Above ``model`` (it chooses among the designs a ``DesignGrid`` holds) and ``flight`` (a
roll rise limit is met by flying candidates). Modules, one job each: ``objectives``
(metric -> cost array), ``exhaustive`` (the enumeration oracle), ``milp_builder`` (a small
modelling layer over ``scipy.optimize.milp``), ``milp_rules`` (the thesis' mixed-logical
rules), ``milp_exact`` (the default exact MILP), ``thesis_formulation`` (Paper E's
linearised MILP, ``--method thesis``), ``selection`` (request -> one design per actuator
count, the tie-break), ``pareto`` (exact two-objective fronts), ``packs`` (cells in series
and parallel), ``roll_rise`` (``optimize --max-roll-rise-ms``) and ``selection_options``
(which request options combine, for ``rotorbench optimize`` and the demo).
"""
