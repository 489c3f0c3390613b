"""Catalog and table files that are not what the sizing commands expect: one line naming
the file and the column, exit code 2."""

from __future__ import annotations

from pathlib import Path

from bench.cli import main
from tests.conftest import CATALOGS, RIGS, SIZINGLAB, run_bad


def test_sizinglab_import_refuses_a_column_named_twice(tmp_path: Path, capsys,
                                                      shared_data: Path) -> None:
    """The same in the SizingLab importer: a repeated header is refused."""
    import shutil

    src = tmp_path / "sizinglab"
    shutil.copytree(SIZINGLAB, src)
    motors = src / "Motors_Data.csv"
    motors.write_text(motors.read_text(encoding="utf-8").replace("Pole_number", "Kv_rpm_v", 1),
                      encoding="utf-8")
    err = run_bad(capsys, "import-sizinglab", "--source", str(src), "--out", str(tmp_path / "cat"))
    assert "Motors_Data.csv: the header names column 'Kv_rpm_v' twice" in err
    assert not (tmp_path / "cat").exists()


def test_other_tables_refuse_a_column_named_twice(tmp_path: Path, capsys,
                                                  fixtures_dir: Path) -> None:
    """The same in every other reader of a CSV header (catalog tables, a rig's
    thrust map, an IMU log) refuses a repeated name."""
    import shutil

    cat = tmp_path / "thesis-e"
    shutil.copytree(CATALOGS / "thesis-e", cat)
    motors = cat / "motors.csv"
    motors.write_text(motors.read_text(encoding="utf-8").replace(",price,", ",mass_g,", 1),
                      encoding="utf-8")
    err = run_bad(capsys, "optimize", "--catalog", str(cat))
    assert "motors.csv: the header names column 'mass_g' twice" in err

    rig = tmp_path / "rig" / "sim.toml"
    shutil.copytree(RIGS, rig.parent)
    (rig.parent / "sim.thrust_map.csv").write_text("command_us,thrust_n,thrust_n\n"
                                                   "1000,0,1\n2000,8,9\n", encoding="utf-8")
    err = run_bad(capsys, "step", "--rig", str(rig), "--dry-run")
    assert "sim.thrust_map.csv: the header names column 'thrust_n' twice" in err

    log = tmp_path / "imu.csv"
    log.write_text("t_s,gyr_x,gyr_x\n0,1,2\n", encoding="utf-8")
    err = run_bad(capsys, "calibrate", "--from-log", str(log), "--out", str(tmp_path / "c.json"))
    assert "imu.csv: the header names column 'gyr_x' twice" in err


def test_catalog_with_semicolons_says_so(tmp_path: Path, capsys, fixtures_dir: Path) -> None:
    """A spreadsheet export with ';' listed every column as missing and nothing else."""
    import shutil

    cat = tmp_path / "cat"
    shutil.copytree(CATALOGS / "thesis-e", cat)
    motors = cat / "motors.csv"
    motors.write_text(motors.read_text().replace(",", ";"))
    err = run_bad(capsys, "optimize", "--catalog", str(cat))
    assert "motors.csv: missing column 'id'" in err
    assert "the header is one field: columns must be separated by commas" in err


def test_catalog_by_shipped_name_and_bad_environment(tmp_path: Path, capsys,
                                                     monkeypatch) -> None:
    """`--catalog thesis-d` (the README names the shipped catalogs) was 'not a catalog
    folder' outside the source tree; a wrong ROTORBENCH_CATALOG blamed the install."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("ROTORBENCH_CATALOG", raising=False)
    assert main(["evaluate", "--catalog", "thesis-d", "--actuators", "4", "--propeller", "P1",
                 "--motor", "M1", "--battery", "B1", "--json"]) == 0
    assert "thesis-d" in capsys.readouterr().out
    monkeypatch.setenv("ROTORBENCH_CATALOG", "nosuch")
    err = run_bad(capsys, "optimize")
    assert "ROTORBENCH_CATALOG=nosuch: not a catalog folder or a shipped catalog name" in err


def test_robot_example_given_as_a_catalog(capsys, fixtures_dir: Path) -> None:
    """It said only 'missing file propellers.csv'."""
    err = run_bad(capsys, "optimize", "--catalog", str(CATALOGS / "thesis-robot"))
    assert "mobile-robot example (robot.toml), not a multirotor catalog" in err


def test_catalog_cell_beyond_1e9_is_refused(tmp_path: Path, capsys, fixtures_dir: Path) -> None:
    import shutil

    cat = tmp_path / "cat"
    shutil.copytree(CATALOGS / "thesis-e", cat)
    lines = (cat / "propellers.csv").read_text().splitlines()
    header = lines[0].split(",")
    row = lines[1].split(",")
    row[header.index("ct")] = "1e308"
    (cat / "propellers.csv").write_text("\n".join([lines[0], ",".join(row), *lines[2:]]) + "\n")
    err = run_bad(capsys, "optimize", "--catalog", str(cat))
    assert "propellers.csv" in err and "column 'ct': expected a number <= 1e+09" in err
