"""Design selection with the options a request may add to ``optimizer.selection.optimize``.

Three options change how the grid is built, and so how ``optimize`` is called:

* measured overrides (a store's ``MeasuredActuator`` set: something with ``build_grid``
  and ``annotate``, e.g. ``bench.measured_constants.MeasuredSet``): every design then
  carries ``sources`` naming what was measured;
* the flyable-design rules (``optimizer.flyable.Rules``): the result then carries
  ``rule_reports``, what each rule removed;
* APC propeller data (``prop_data``: a ``build`` grid builder and its ``coefficients``).

Which combinations work is decided here, once, for ``rotorbench optimize`` and the demo.
"""

from __future__ import annotations

from typing import Any, Protocol

from optimizer.errors import RequestError
from optimizer.objectives import Objective

__all__ = ["MeasuredGrids", "solve"]


class MeasuredGrids(Protocol):
    """Measured overrides as a grid builder: builds grids with them, then marks sources."""

    def build_grid(self, catalog: Any, n: int, payload_kg: float) -> Any: ...

    def annotate(self, result: Any) -> None: ...


def solve(catalog: Any, objective: Objective, actuators: tuple[int, ...], requirements: Any,
          method: str, measured: MeasuredGrids | None = None, rules: Any = None,
          prop_data: dict[str, Any] | None = None) -> Any:
    """``optimizer.selection.optimize``, with the measured overrides when given (then every
    design carries ``sources``) and the flyable-design rules when given (then the result
    carries ``rule_reports``)."""
    from optimizer.selection import optimize

    if method == "thesis" and (measured is not None or rules is not None):
        raise RequestError("--measured and --flyable work with --method milp or exact (the "
                           "thesis formulation linearises the datasheet model)")
    if prop_data is not None and (measured is not None or method == "thesis"):
        raise RequestError("--prop-data works with --method milp or exact, without --measured")
    build = None if measured is None else measured.build_grid
    coefficients = None
    if prop_data is not None:
        build, coefficients = prop_data["build"], prop_data["coefficients"]
    builder = None
    if rules is not None:
        from optimizer.flyable import FlyableBuilder

        build = builder = FlyableBuilder(rules, build, coefficients=coefficients)
    result = optimize(catalog, objective, actuators, requirements, method, build_grid=build)
    if measured is not None:
        measured.annotate(result)
    if builder is not None:
        result.rule_reports = [r.to_dict() for r in builder.reports]
    return result
