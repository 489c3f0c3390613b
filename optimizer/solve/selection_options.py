"""Design selection with the options a request may add to ``optimizer.solve.selection.optimize``.

Three options change how the grid is built, and so how ``optimize`` is called:

* measured overrides (a store's ``MeasuredActuator`` set: something with ``build_grid``
  and ``annotate``, e.g. ``bench.store.measured_constants.MeasuredSet``): every design then
  carries ``sources`` naming what was measured;
* the flyable-design rules (``optimizer.model.flyable.Rules``): the result then carries
  ``rule_reports``, what each rule removed;
* APC propeller data (:func:`prop_data_option`: a ``build`` grid builder, its
  ``coefficients`` and the match ``report``).

Two more change what is solved: cells in series and parallel (:func:`solve_packs`,
``optimizer.solve.packs``) and a closed-loop roll rise limit (:func:`meet_roll_rise_option`,
``optimizer.solve.roll_rise``). Which combinations work is decided here, once, for
``rotorbench optimize`` and the demo.
"""

from __future__ import annotations

from typing import Any, Protocol

from optimizer.catalogs.catalog import Catalog
from optimizer.errors import RequestError
from optimizer.solve.objectives import Objective

__all__ = ["MeasuredGrids", "grid_builder", "meet_roll_rise_option", "pack_grid_builder",
           "prop_data_option", "solve", "solve_packs"]


class MeasuredGrids(Protocol):
    """Measured overrides as a grid builder: builds grids with them, then marks sources."""

    def build_grid(self, catalog: Catalog, n: int, payload_kg: float) -> Any: ...

    def annotate(self, result: Any) -> None: ...


def solve(catalog: Catalog, objective: Objective, actuators: tuple[int, ...], requirements: Any,
          method: str, measured: MeasuredGrids | None = None, rules: Any = None,
          prop_data: dict[str, Any] | None = None) -> Any:
    """``optimizer.solve.selection.optimize``, with the measured overrides when given (then every
    design carries ``sources``) and the flyable-design rules when given (then the result
    carries ``rule_reports``)."""
    from optimizer.solve.selection import optimize

    if method == "thesis" and (measured is not None or rules is not None):
        raise RequestError("--measured and --flyable work with --method milp or exact (the "
                           "thesis formulation linearises the datasheet model)")
    if prop_data is not None and (measured is not None or method == "thesis"):
        raise RequestError("--prop-data works with --method milp or exact, without --measured")
    build, builder = grid_builder(measured, rules, prop_data)
    result = optimize(catalog, objective, actuators, requirements, method, build_grid=build)
    if measured is not None:
        measured.annotate(result)
    if builder is not None:
        # an attribute of this result only (not a field of every SelectionResult)
        result.rule_reports = [  # pyright: ignore[reportAttributeAccessIssue]
            r.to_dict() for r in builder.reports]
    return result


def grid_builder(measured: MeasuredGrids | None, rules: Any,
                 prop_data: dict[str, Any] | None = None) -> tuple[Any, Any]:
    """(grid builder for ``optimize``, the ``FlyableBuilder`` when rules apply, else None):
    the grids ``optimize`` chooses from, which the flight sweep flies too."""
    build = None if measured is None else measured.build_grid
    coefficients = None
    if prop_data is not None:
        build, coefficients = prop_data["build"], prop_data["coefficients"]
    builder = None
    if rules is not None:
        from optimizer.model.flyable import FlyableBuilder

        build = builder = FlyableBuilder(rules, build, coefficients=coefficients)
    return build, builder


def prop_data_option(catalog: Catalog) -> dict[str, Any]:
    """The APC static C_t(rpm), C_p(rpm) as a ``prop_data`` option: ``build`` (the model
    grid with them), ``coefficients`` and ``report`` (which catalog propellers matched)."""
    from functools import partial

    from optimizer.model.design_model import evaluate_grid
    from optimizer.model.propdata import catalog_curves, data_folder, load_curves, match_report

    table = catalog_curves(catalog, load_curves(data_folder()))
    return {"build": partial(evaluate_grid, coefficients=table.coefficients),
            "coefficients": table.coefficients, "report": match_report(catalog, table)}


def solve_packs(catalog: Catalog, objective: Objective, actuators: tuple[int, ...],
                requirements: Any, method: str, series: tuple[int, ...],
                parallel: tuple[int, ...], measured: MeasuredGrids | None = None,
                rules: Any = None, prop_data: dict[str, Any] | None = None) -> Any:
    """``optimizer.solve.packs.optimize_packs`` (S and P chosen too) with the same options as
    :func:`solve` except measured overrides; the rule reports of the per-S grids are
    added up per actuator count."""
    from optimizer.solve.packs import optimize_packs

    build, builder = pack_grid_builder(measured, rules, prop_data)
    result = optimize_packs(catalog, objective, actuators, requirements, method, series,
                            parallel, build_grid=build)
    if builder is not None:
        # an attribute of this result only (not a field of every SelectionResult)
        result.rule_reports = _sum_reports(  # pyright: ignore[reportAttributeAccessIssue]
            builder.reports)
    return result


def pack_grid_builder(measured: MeasuredGrids | None, rules: Any,
                      prop_data: dict[str, Any] | None = None) -> tuple[Any, Any]:
    """:func:`grid_builder` for series/parallel packs, which take no measured overrides."""
    if measured is not None:
        raise RequestError("--series/--parallel do not combine with --measured (measured "
                           "currents belong to the bench's supply voltage)")
    return grid_builder(None, rules, prop_data)


def _sum_reports(reports: list[Any]) -> list[dict[str, Any]]:
    """Rule reports of the per-S grids added up per actuator count."""
    out: dict[int, dict[str, Any]] = {}
    for r in reports:
        d = r.to_dict()
        zero = {key: 0 for key in ("designs", "physically_feasible", "flyable")}
        acc = out.setdefault(d["actuators"], {
            **d, **zero,
            "removed_alone": dict.fromkeys(d["removed_alone"], 0),
            "removed_in_turn": dict.fromkeys(d["removed_in_turn"], 0),
        })
        for key in ("designs", "physically_feasible", "flyable"):
            acc[key] += d[key]
        for key in ("removed_alone", "removed_in_turn"):
            for name, v in d[key].items():
                acc[key][name] += v
    return list(out.values())


def meet_roll_rise_option(result: Any, catalog: Catalog, objective: Objective, requirements: Any,
                          method: str, max_roll_rise_ms: float,
                          measured: MeasuredGrids | None = None, screen: Any = None) -> Any:
    """A roll rise limit on a selection: fly the picks, then candidates in objective order
    (``optimizer.solve.roll_rise.meet_roll_rise``), on the measured grids when given; with
    ``screen`` (``optimizer.sweep.sweep_screen.roll_screen``) read from a sweep file."""
    from optimizer.solve.roll_rise import meet_roll_rise

    if method == "thesis":
        raise RequestError("--max-roll-rise-ms works with --method milp or exact")
    result = meet_roll_rise(result, catalog, objective, requirements, max_roll_rise_ms,
                            build_grid=None if measured is None else measured.build_grid,
                            screen=screen)
    if measured is not None:
        measured.annotate(result)
    return result
