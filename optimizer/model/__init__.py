"""The design model: every metric of every (propeller, motor, battery) design, exactly.

Above ``catalogs``, below everything that chooses or flies. Modules, one job each:
``physics`` (Papers D and E's hover physics as broadcasting numpy functions),
``operating_points`` (a drive at any throttle, as eCalc reports it), ``battery`` (the
Shepherd discharge model), ``measured`` (bench-measured actuator constants that replace
modelled ones), ``propdata`` (APC's measured C_t(rpm), C_p(rpm) matched to a catalog),
``grid`` (``DesignGrid`` and ``Check``: the contract with the solvers, and the one
feasibility test), ``design_model`` (``evaluate_grid``: the grid of one actuator count),
``sheet`` (one design as an eCalc sheet) and ``flyable`` (the flyable-design rules as
extra checks on a grid).
"""
