"""``heliostep size``: choose a motor and a current for a scenario's drive (:mod:`heliostep.sizing.size`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from heliostep.cli.signals import stop_requests
from heliostep.cli.sweep import add_family_options, case_count

#: The defaults of heliostep.sizing.size (imported when the command runs: every command's start stays short).
ALL_DAYS = "all"
DEFAULT_SAFETY_FACTOR = 2.0
DEFAULT_CURVE_RATES = (5.0, 500.0, 1000.0, 2000.0, 3000.0)

SIZE_DESCRIPTION = (
    "Judge every candidate drive of a motor catalogue, at each of its currents, against the scenario's load: "
    "the load budget at the worst instant (the design wind moment through the transmission, friction, the "
    "inertia torque of the fastest move), the margins to slip while tracking, at idle current and while stowing "
    "(a stow move at the slew rate in the stow wind, against the candidate's co-simulated speed-torque curve), "
    "and the scenario's window co-simulated on each day with the candidate's motor (steps missed and lost, worst "
    "tracking error, drive energy). A candidate passes when the three margins (tracking, idle, stowing) reach "
    "the safety factor, no step is missed or lost and every day's co-simulation completed. Each day is "
    "co-simulated once more at the worst corner of the drive physics' ranges "
    "(data/parameter_ranges.yaml: the lowest bus and loop gain, the highest rotor damping), shown in the band "
    "beside the verdict (--no-band-days: not). Writes sizing.json and sizing.html (self-contained, one "
    "printed page per section) into --out: first the verdict (the drive chosen, its governing case and margin, "
    "why the next smaller one fails), then what it was sized for (site, window and days, mirror, transmission, "
    "wind, safety factor, every --set, the files' sha256, the versions).\n\n"
    "Wind: --design-gust, or the scenario's wind.speed, wind.weather_file, wind.profile or wind.moment; with "
    "none of them the sizing is refused (exit 2): it does not size against no wind.\n\n"
    "Days: --days DOY ..., or --days all (every day of the year, meant for --scheduler); else the days that "
    "matter, found over the scenario's year: the sun's fastest days (the peaks of the year's curve of the ideal "
    "panel angle's largest rate within the window) and, with wind.weather_file, the year's windiest days (the "
    "highest mean wind speed within the window); the sheet says which and why. The cases run "
    "here one after another, or on a Dask cluster with --scheduler; the speed-torque curves on every core. Ctrl+C "
    "(SIGINT), SIGTERM or SIGHUP stops after the case (or the curves) in progress: the sheet is written with the "
    "cases finished, marked complete: false, naming those not run.\n\n"
    "Before any simulation the cases are counted (candidates' currents x days, x 2 with the worst corner's days) "
    "and refused over --max-cases, naming the catalogue entry or --days that makes them many; the largest case's "
    "memory is estimated and refused over budget.memory_gb (--set budget.memory_gb=GB). A sheet --out cannot take "
    "(a full disk) is written as sizing.json into a rescue folder, named on stderr, exit 1.\n\n"
    "Exit status: 0 written (whatever the verdicts); 1 a failure (the sheet not written: rescued); 2 bad input "
    "(scenario, catalogue: unknown candidate, an entry missing a value; a bad option; no wind; too many cases, "
    "over the budget), before any simulation; 130 / 143 / 129 stopped."
)


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "size",
        help="choose a motor and current: the sizing sheet (sizing.json, sizing.html)",
        description=SIZE_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("scenario", help="scenario YAML (or a shipped scenario's name)")
    parser.add_argument(
        "--catalogue", type=Path, default=None, help="motor catalogue (default heliostep/data/motors.yaml)"
    )
    parser.add_argument("--candidate", action="append", default=[], help="only this catalogue entry (repeatable)")
    parser.add_argument(
        "--design-gust",
        type=float,
        default=None,
        metavar="M_PER_S",
        help="design gust [m/s] (else the scenario's wind; one of the two is required)",
    )
    parser.add_argument(
        "--days",
        nargs="+",
        default=[],
        metavar="DOY",
        help=f"days of the year to simulate (1..365), or {ALL_DAYS!r} (default: the fastest and windiest days)",
    )
    parser.add_argument("--safety-factor", type=float, default=DEFAULT_SAFETY_FACTOR, help="on the load (default 2)")
    parser.add_argument(
        "--curve-rates",
        type=float,
        nargs="+",
        default=list(DEFAULT_CURVE_RATES),
        metavar="RATE",
        help="step rates of the speed-torque curves [full steps/s]",
    )
    parser.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="override a scenario key (as for run)"
    )
    parser.add_argument(
        "--no-band-days",
        action="store_true",
        help="do not co-simulate the days again at the drive physics' worst corner (the band's steps and error)",
    )
    parser.add_argument(
        "--max-cases",
        type=case_count,
        default=None,
        metavar="N",
        help="refuse a sizing of more cases than this, before any runs (default: as many as a sweep may have)",
    )
    add_family_options(parser)
    parser.add_argument("--out", default=None, help="output folder (default out/<scenario>-sizing)")
    parser.add_argument("--scheduler", default=None, metavar="ADDR", help="Dask scheduler (tcp://HOST:PORT)")
    parser.set_defaults(func=main)


def _days(values: list[str]) -> list[int] | str:
    """``--days``: day numbers, or the one word ``all``."""
    from heliostep.errors import InputError

    if values == [ALL_DAYS]:
        return ALL_DAYS
    try:
        return [int(value) for value in values]
    except ValueError:
        raise InputError(f"--days {' '.join(values)}: expected days of the year (1..365) or {ALL_DAYS!r}") from None


def main(args: argparse.Namespace) -> int:
    from heliostep.results.output.files import check_out_name
    from heliostep.scenario.catalogue import load_catalogue, shipped_catalogue_path
    from heliostep.sizing.sheet import size
    from heliostep.sizing.size import plan_sizing

    out_name = check_out_name(args.out) if args.out is not None else None  # "" refused before anything
    candidates = load_catalogue(args.catalogue, args.candidate)
    catalogue = str(args.catalogue or shipped_catalogue_path())
    limit = {} if args.max_cases is None else {"max_cases": args.max_cases}
    plan = plan_sizing(
        args.scenario,
        candidates,
        design_gust=args.design_gust,
        days=_days(args.days),
        safety_factor=args.safety_factor,
        curve_rates=args.curve_rates,
        overrides=args.set,
        band_days=not args.no_band_days,
        catalogue=catalogue,
        **limit,
    )
    out = out_name or Path("out") / f"{plan.scenario.name}-sizing"
    with stop_requests() as stop:
        sheet = size(
            plan,
            out,
            scheduler=args.scheduler,
            progress=True,
            should_stop=stop.is_set,
            catalogue=catalogue,
            exact=args.exact,
            certify=args.certify,
            seed=args.seed,
        )
    best = sheet["smallest_passing"]
    print(f"sizing sheet: {out / 'sizing.html'}, {out / 'sizing.json'}")
    if not sheet["complete"]:
        print(
            f"interrupted: {len(sheet['finished_cases'])} cases finished and kept; not run: "
            f"{', '.join(sheet['unfinished_cases'])}",
            file=sys.stderr,
        )
        return stop.exit_status if stop.is_set() else 1
    print(f"smallest passing: {best['candidate']} at {best['current_A']:g} A" if best else "no candidate passes")
    return 0
