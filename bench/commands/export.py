"""``rotorbench export {ardupilot,px4,gazebo} RUN``: fitted curves as autopilot parameters."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from analysis.errors import LogError
from bench.cli_args.store_args import add_store_args, run_folder_arg
from bench.errors import RigError

G0 = 9.80665


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "export", help="export fitted curves as ArduPilot / PX4 / Gazebo parameters",
        description="ardupilot: MOT_THST_EXPO (+ MOT_SPIN_MIN/MAX where the data shows them, "
                    "MOT_THST_HOVER with --hover-thrust or --auw-kg/--motors); px4: "
                    "THR_MDL_FAC; gazebo: the multirotor motor model plugin parameters. RUN is "
                    "a sweep or an imported stand log with command and thrust (or rpm with "
                    "--thrust-run).")
    p.add_argument("target", choices=("ardupilot", "px4", "gazebo"))
    p.add_argument("run", type=Path, help="run folder (or run id of --store) with the static "
                   "data")
    add_store_args(p)
    p.add_argument("--thrust-run", type=Path, default=None,
                   help="run with thrust against rpm, if RUN logs rpm but no thrust")
    p.add_argument("--step-run", type=Path, default=None,
                   help="gazebo: step run for timeConstantUp/Down (fitted on rpm)")
    p.add_argument("--hover-thrust", type=float, default=None,
                   help="ardupilot: hover thrust per motor in newtons")
    p.add_argument("--auw-kg", type=float, default=None, help="ardupilot: all-up weight (kg)")
    p.add_argument("--motors", type=int, default=None, help="ardupilot: number of motors")
    p.add_argument("--json", action="store_true", help="print JSON instead of parameter lines")
    p.add_argument("--out", type=Path, default=None,
                   help="write the parameters to this file instead of printing them, and "
                        "beside it <name>.uncertainty.json: each exported constant's value, "
                        "u, U, k, dof_eff, budget, run and calibration records")
    p.set_defaults(func=handler)


def _hover(args: argparse.Namespace) -> float | None:
    if args.hover_thrust is not None:
        if not (np.isfinite(args.hover_thrust) and args.hover_thrust > 0):
            raise RigError(f"--hover-thrust: expected a thrust per motor > 0 N, "
                           f"got {args.hover_thrust:g}")
        return float(args.hover_thrust)
    if args.auw_kg is not None or args.motors is not None:
        if args.auw_kg is None or args.motors is None:
            raise RigError("--auw-kg and --motors go together (positive weight, >= 1 motor)")
        # `not x > 0` also refuses NaN (NaN <= 0 is False: it used to print MOT_THST_HOVER,nan)
        if not (np.isfinite(args.auw_kg) and args.auw_kg > 0):
            raise RigError(f"--auw-kg: expected an all-up weight > 0 kg, got {args.auw_kg:g}")
        if args.motors < 1:
            raise RigError(f"--motors: expected a count >= 1, got {args.motors}")
        return args.auw_kg * G0 / args.motors
    return None


def _check_finite(out: dict[str, Any], source: Path) -> None:
    """Refuse to print a parameter the fit left NaN or infinite (an autopilot would take
    ``nan`` as a value; ``--json`` cannot encode it)."""
    for name, value in out.items():
        if isinstance(value, float) and not np.isfinite(value):
            raise LogError(f"{source}: the fit gives no finite {name} ({value}); "
                           "the run does not support this export")


def build(args: argparse.Namespace) -> tuple[dict[str, Any], tuple[Any, Any, Any], Any]:
    """The parameters of ``args.target`` (one home: ``analysis.exports.export_params``,
    which the web view's downloads use too), after the options are checked; the run
    records they came from (run, thrust run, step run: None where not given), read once;
    and a Gazebo export's fits (else None), made once for the parameters and the sidecar."""
    from analysis.exports import export_params, gazebo_fits
    from analysis.run_record import read_run
    from bench.cli_args.option_values import refuse_unused

    if args.target != "ardupilot":  # MOT_THST_HOVER is ArduPilot's; PX4, Gazebo have none
        refuse_unused(args, ("--hover-thrust", "--auw-kg", "--motors"),
                      f"for export {args.target} (only ardupilot uses a hover thrust)")
    if args.target != "gazebo":  # the time constants go into Gazebo's motor model only
        refuse_unused(args, ("--step-run",),
                      f"for export {args.target} (only gazebo uses time constants)")
    hover = _hover(args)  # options first: a bad one is named before any fit
    records = (read_run(args.run), read_run(args.thrust_run) if args.thrust_run else None,
               read_run(args.step_run) if args.step_run is not None else None)
    fits = gazebo_fits(*records) if args.target == "gazebo" else None
    out = export_params(args.target, *records, hover, fits=fits)
    _check_finite(out, records[0].path)
    return out, records, fits


def handler(args: argparse.Namespace) -> int:
    for name in ("run", "thrust_run", "step_run"):
        if getattr(args, name) is not None:
            setattr(args, name, run_folder_arg(args, getattr(args, name)))
    if args.out is not None:
        from bench.paths.outputs import check_writable

        check_writable(args.out, "--out", folder=False)
    out, records, fits = build(args)
    text = json.dumps(out, indent=2, allow_nan=False) if args.json else _lines(args, out)
    if args.out is None:
        print(text)
        return 0
    from analysis.export_uncertainty import export_uncertainties

    side = export_uncertainties(args.target, out, *records, fits=fits)
    side_text = json.dumps(side, indent=2, allow_nan=False)  # both made before either is written
    args.out.write_text(text + "\n", encoding="utf-8")
    sidecar = sidecar_path(args.out)
    sidecar.write_text(side_text + "\n", encoding="utf-8")
    print(f"wrote {args.out} and {sidecar}")
    return 0


def sidecar_path(out: Path) -> Path:
    """``<name>.uncertainty.json`` beside the exported file ``<name>.<ext>``."""
    return out.with_name(f"{out.stem}.uncertainty.json")


def _lines(args: argparse.Namespace, out: dict[str, Any]) -> str:
    """The parameters as the target's own lines, the fit's remarks as comments."""
    lines = []
    if args.target == "ardupilot":
        for name in ("MOT_THST_EXPO", "MOT_SPIN_MIN", "MOT_SPIN_MAX", "MOT_THST_HOVER"):
            if out.get(name) is not None:
                lines.append(f"{name},{out[name]}")
        lines.append(f"# fit rms {out['fit_rms']:.4f} (normalised thrust); WebTools criterion "
                     f"gives {out['expo_webtool']:.3f}; command axis {out['command_axis']}")
    elif args.target == "px4":
        lines.append(f"param set THR_MDL_FAC {out['THR_MDL_FAC']}")
        lines.append(f"# fit rms {out['fit_rms']:.4f} (normalised thrust); command axis "
                     f"{out['command_axis']}")
    else:
        for name in ("motorConstant", "momentConstant", "timeConstantUp", "timeConstantDown",
                     "maxRotVelocity"):
            if out.get(name) is not None:
                lines.append(f"<{name}>{out[name]}</{name}>")
    lines += [f"# {n}" for n in out.get("notes", [])]
    return "\n".join(lines)
