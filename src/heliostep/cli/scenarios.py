"""``heliostep scenarios``: the shipped scenarios, each by the name ``run`` takes and its description."""

from __future__ import annotations

import argparse

SCENARIOS_DESCRIPTION = (
    "List the scenarios shipped with heliostep (heliostep/data/scenarios, or the checkout's scenarios/): each "
    "one's name, which `heliostep run NAME` and `heliostep size NAME` take from any folder, and its description "
    "(the scenario's own `description`).\n\n"
    "Exit status: 0 listed; 2 a shipped scenario that cannot be read (the file named)."
)


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "scenarios",
        help="list the shipped scenarios (name and description)",
        description=SCENARIOS_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from heliostep.scenario.load import shipped_scenario_dir, shipped_scenarios

    shipped = shipped_scenarios()  # an unreadable file: InputError, exit 2 naming it
    print(f"{shipped_scenario_dir()}: {len(shipped)} scenarios")
    print(scenario_table([(name, text or "-") for name, text in shipped.items()]))
    return 0


def scenario_table(rows: list[tuple[str, str]]) -> str:
    """(name, description) rows as an aligned text table, one line each, under a header."""
    width = max(len(name) for name, _ in [("name", ""), *rows])
    return "\n".join(f"{name.ljust(width)}  {text}".rstrip() for name, text in [("name", "description"), *rows])
