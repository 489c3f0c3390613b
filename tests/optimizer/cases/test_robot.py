"""Section 2.4.1: the mobile-robot battery selection, derived by the MILP."""

from __future__ import annotations

from pathlib import Path

import pytest

from optimizer.cases.robot import load_robot, solve_robot
from optimizer.errors import CatalogError
from tests.conftest import CATALOGS


@pytest.fixture
def robot(fixtures_dir: Path):
    return load_robot(CATALOGS / "thesis-robot")


def test_fixture_is_table_2_2(robot) -> None:
    assert robot.battery_ids == ("1", "2", "3", "4")
    assert list(robot.capacity_ah) == [10, 20, 30, 40]
    assert list(robot.battery_mass_kg) == [1, 2, 3, 4]
    assert list(robot.battery_price) == [100, 200, 300, 400]
    assert robot.regions == 10 and robot.power_limit_w == 30


def test_power_limited_choice_is_battery_3_with_linearised_power(robot) -> None:
    r = solve_robot(robot)
    assert r.status == "optimal"
    assert r.battery == "3"
    assert r.weight_kg == pytest.approx(5.0)
    assert r.current_a == pytest.approx(5.0)
    assert r.runtime_h == pytest.approx(6.0)
    assert r.power_w == pytest.approx(25.08, abs=1e-6)  # the thesis' CPLEX value
    assert r.power_exact_w == pytest.approx(25.0)
    assert r.active_region == 9
    # Tables 2.3-2.4: x1..x30, 14 of them Boolean
    assert (r.n_vars, r.n_binary) == (30, 14)
    # the thesis' A has 97 rows (2.66), 28 of them the 0 <= delta <= 1 rows (2.48)-(2.49)
    # of the 14 Booleans, which milp takes as variable bounds
    assert r.n_constraints == 97 - 2 * 14


def test_without_power_limit_battery_4_wins(robot) -> None:
    r = solve_robot(robot.with_(power_limit_w=None))
    assert r.battery == "4"
    assert r.runtime_h == pytest.approx(40 / 6)
    assert r.power_w == pytest.approx(36.0)  # a breakpoint: exact


def test_printed_2_A_per_kg_makes_the_example_infeasible(robot) -> None:
    r = solve_robot(robot.with_(current_per_kg_a=2.0))
    assert r.status == "infeasible" and r.battery is None


def test_more_regions_shrink_the_linearisation_error(robot) -> None:
    errors = [abs(solve_robot(robot.with_(regions=n)).power_w - 25.0) for n in (3, 10, 60)]
    assert errors[0] > errors[1] > errors[2]


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("id,capacity_ah,mass_kg\n1,10,1\n", "missing column"),
        ("id,capacity_ah,mass_kg,price\n1,ten,1,100\n", "row 2, column capacity_ah"),
        ("id,capacity_ah,mass_kg,price\n1,10,1,100\n1,20,2,200\n", "row 3, column id"),
        ("id,capacity_ah,mass_kg,price\n1,10,-1,100\n", "row 2, column mass_kg"),
        ("id,capacity_ah,mass_kg,price\n", "no battery rows"),
    ],
)
def test_bad_robot_files_name_row_and_column(tmp_path: Path, text: str, match: str) -> None:
    (tmp_path / "batteries.csv").write_text(text)
    with pytest.raises(CatalogError, match=match) as exc:
        load_robot(tmp_path)
    assert exc.value.exit_code == 2
    assert "batteries.csv" in str(exc.value)


@pytest.mark.parametrize(
    ("toml", "match"),
    [
        ("robot_mass_kg = -2\n", "robot_mass_kg: expected > 0"),
        ("robot_mass = 2\n", "unknown key 'robot_mass'"),
        ("regions = 'ten'\n", "regions: expected a number"),
        ("regions = \n", "not valid TOML"),
    ],
)
def test_bad_robot_constants_name_the_key(tmp_path: Path, toml: str, match: str) -> None:
    (tmp_path / "batteries.csv").write_text("id,capacity_ah,mass_kg,price\n1,10,1,100\n")
    (tmp_path / "robot.toml").write_text(toml)
    with pytest.raises(CatalogError, match=match) as exc:
        load_robot(tmp_path)
    assert "robot.toml" in str(exc.value)
