"""Worked cases of the papers and the thesis, solved with ``optimizer.solve``.

The top floor beside ``sweep``: nothing in ``optimizer`` imports a case. Modules:
``paper_e_cases`` (Paper E's three test cases, one home for ``optimize --paper-e-cases``
and the demo) and ``robot`` (thesis section 2.4.1: a mobile robot's battery by MILP, the
example that introduces the rules).
"""
