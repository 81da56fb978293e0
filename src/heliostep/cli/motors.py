"""``heliostep motors``: the motor catalogue as a table (:mod:`heliostep.scenario.catalogue`)."""

from __future__ import annotations

import argparse
from pathlib import Path

MOTORS_DESCRIPTION = (
    "List a motor catalogue (default the shipped heliostep/data/motors.yaml): each entry's name, frame, maker, "
    "holding torque (two phases on, at the rated current), rated current, phase resistance and inductance, rotor "
    "inertia, detent torque, full-step angle, the datasheet's test voltage and the document its values come "
    "from. Every entry is checked as `heliostep size` and `heliostep run --motor` check it.\n\n"
    "Exit status: 0 listed; 2 a bad catalogue (the file and the dotted key named)."
)

#: (header, the entry's value as text) of each column, in order.
_COLUMNS = (
    ("name", lambda c: c.name),
    ("frame", lambda c: c.frame or "-"),
    ("maker", lambda c: c.manufacturer),
    ("T_hold [N.m]", lambda c: f"{c.holding_torque:g}"),
    ("I_rated [A]", lambda c: f"{c.rated_current:g}"),
    ("R [Ohm]", lambda c: f"{c.resistance:g}"),
    ("L [mH]", lambda c: f"{c.inductance * 1e3:g}"),
    ("J_m [g.cm2]", lambda c: f"{c.rotor_inertia * 1e7:.4g}"),
    ("T_d [N.m]", lambda c: f"{c.detent_torque:g}"),
    ("step [deg]", lambda c: f"{c.step_angle:g}"),
    ("V_test [V]", lambda c: "-" if c.test_voltage is None else f"{c.test_voltage:g}"),
    ("source", lambda c: c.datasheet),
)


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "motors",
        help="list the motor catalogue (datasheet values and their sources)",
        description=MOTORS_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--catalogue", type=Path, default=None, help="motor catalogue (default heliostep/data/motors.yaml)"
    )
    parser.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from heliostep.scenario.catalogue import load_catalogue, shipped_catalogue_path

    candidates = load_catalogue(args.catalogue)  # an InputError: exit 2, naming the file and the key
    print(f"{args.catalogue or shipped_catalogue_path()}: {len(candidates)} motors")
    print(motor_table(candidates))
    return 0


def motor_table(candidates) -> str:
    """The entries as an aligned text table, one line each, under a header."""
    rows = [[header for header, _ in _COLUMNS]] + [[value(c) for _, value in _COLUMNS] for c in candidates]
    widths = [max(len(row[k]) for row in rows) for k in range(len(_COLUMNS) - 1)]
    lines = ["  ".join([*(cell.ljust(width) for cell, width in zip(row, widths)), row[-1]]) for row in rows]
    return "\n".join(line.rstrip() for line in lines)
