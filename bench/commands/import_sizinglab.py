"""``rotorbench import-sizinglab``: write the SizingLab CSVs as a catalog folder.

The SizingLab lists (Apache-2.0, semicolon-separated, their own column names)
lack prices, propeller masses and rotor inertias; the importer fills them from
the assumptions documented in docs/optimizer.md. The folder is written beside
its final name and renamed into place, so a failure leaves nothing half-written.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    from optimizer.catalogs.sizinglab import DEFAULT_FOLDER

    p = subparsers.add_parser(
        "import-sizinglab",
        help="convert the SizingLab catalogs into a rotorbench catalog folder",
        description="Read Propeller_Data.csv, Motors_Data.csv, Batteries_Data.csv and "
        "Batteries_Data_2.csv from the SizingLab folder and write propellers.csv, "
        "motors.csv, batteries.csv and catalog.toml to --out (must not exist).",
    )
    p.add_argument("--source", type=Path, default=DEFAULT_FOLDER, help="SizingLab folder")
    p.add_argument("--out", type=Path, required=True, help="new catalog folder")
    p.set_defaults(func=handler)


def handler(args: argparse.Namespace) -> int:
    from bench.paths.outputs import check_writable
    from optimizer.catalogs.catalog import load_catalog
    from optimizer.catalogs.sizinglab import import_to_folder

    check_writable(args.out, "--out", folder=True, beside=True)
    out = import_to_folder(args.source, args.out)
    catalog = load_catalog(out)
    print(
        f"wrote {out}: {len(catalog.propellers)} propellers, {len(catalog.motors)} motors, "
        f"{len(catalog.batteries)} batteries"
    )
    return 0
