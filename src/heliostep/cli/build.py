"""``heliostep build-fmus``: compile the Modelica models to FMI 2.0 (or 3.0) Model Exchange FMUs."""

from __future__ import annotations

import argparse
from pathlib import Path

from heliostep.fmu.build import build_all, copy_fmu


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "build-fmus",
        help="compile the Modelica models to FMI 2.0 (or 3.0) Model Exchange FMUs",
        description="Compile models/NAME.mo to NAME.fmu (--fmi 3: NAME-fmi3.fmu) in the FMU cache "
        "(pymoca -> CasADi -> C -> gcc). Up-to-date FMUs are kept unless --force is given.",
    )
    parser.add_argument(
        "--model", action="append", metavar="NAME", help="build only this model (repeatable); default: all models"
    )
    parser.add_argument(
        "--out",
        type=Path,
        metavar="DIR",
        help="also copy each FMU to DIR/NAME.fmu (they are built in the FMU cache, $HELIOSTEP_FMUS)",
    )
    parser.add_argument("--models", type=Path, metavar="DIR", help="Modelica folder (default: models/)")
    parser.add_argument("--force", action="store_true", help="rebuild even if up to date")
    parser.add_argument(
        "--fmi",
        type=int,
        choices=(2, 3),
        default=2,
        help="FMI version of the FMUs: 2 (FMI 2.0, the default) or 3 (FMI 3.0, NAME-fmi3.fmu)",
    )
    parser.set_defaults(func=_run_build)


def _run_build(args: argparse.Namespace) -> int:
    for path in build_all(args.model, None, args.models, args.force, args.fmi):
        print(copy_fmu(path, args.out) if args.out else path)
    return 0
