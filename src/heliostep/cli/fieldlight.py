"""``heliostep field-light``: light on the tube of every end mirror per day of a year, with the shared primary.

Details: docs/light.md, ``heliostep.cli.fieldlight``.
"""

from __future__ import annotations

import argparse
import datetime as dt
from pathlib import Path

from heliostep.progress import progress_bar
from heliostep.results.light.field import field_light_days
from heliostep.results.output.files import check_out_name
from heliostep.results.output.folder import owned_folder, write_swapped
from heliostep.scenario import load_scenario


def register(subparsers) -> argparse.ArgumentParser:
    """Add the ``field-light`` command."""
    parser = subparsers.add_parser(
        "field-light",
        help="energy on the tube per day and mirror of the field with the shared primary",
        description=__doc__.split("\n\n", 1)[0],
    )
    parser.add_argument("scenario", type=Path, help="scenario YAML (site, plant, optics, mirror.spacing)")
    parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE", help="override a scenario key"
    )
    parser.add_argument("--days", type=int, nargs="+", help="days of the year (default all)")
    parser.add_argument("--step-minutes", type=float, default=10.0, help="[min] time step (default 10)")
    parser.add_argument(
        "--no-shading", action="store_true", help="no shading or blocking between the field's mirrors (the old model)"
    )
    parser.add_argument(
        "--shading-step-minutes", type=float, default=30.0, help="[min] time step of shading and blocking (default 30)"
    )
    parser.add_argument("--out", help="output folder (default out/<scenario name>-field-light)")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNGs")
    parser.set_defaults(func=_field_light_command)
    return parser


#: The table of the days and mirrors.
DAYS_FILE = "field_light_days.csv"
#: The heatmaps: (column, PNG, colour-bar label, factor from the column's unit to the bar's).
HEATMAPS = (
    ("light_lost_J", "heatmap_light_lost_year.png", "light lost to the shared primary per day [MJ]", 1e-6),
    (
        "light_lost_fraction",
        "heatmap_light_lost_fraction_year.png",
        "light lost to the shared primary, share of ideal tracking [%]",
        100.0,
    ),
)


def _field_light_command(args: argparse.Namespace) -> int:
    out_name = check_out_name(args.out) if args.out is not None else None  # "" refused before anything
    scenario = load_scenario(args.scenario, args.overrides)
    out = out_name or Path("out") / f"{scenario.name}-field-light"
    year = scenario.window.date.year
    n_days = len(args.days) if args.days else (dt.date(year + 1, 1, 1) - dt.date(year, 1, 1)).days
    with (
        owned_folder(out, [DAYS_FILE, *(name for _, name, _, _ in HEATMAPS)]),  # the lock for the command's life
        progress_bar(n_days, "field light", "day") as bar,
    ):
        table = field_light_days(
            scenario,
            days=args.days,
            step_minutes=args.step_minutes,
            shading=not args.no_shading,
            shading_step_minutes=args.shading_step_minutes,
            progress=bar.update,
        )
        written = list(write_swapped(out, lambda staging: _write_table(args, table, staging)).values())
    _print_year(scenario, table, shading=not args.no_shading)
    for path in written:
        print(f"  wrote {path}")
    return 0


def _write_table(args: argparse.Namespace, table, folder: Path) -> list[Path | None]:
    """The table and (unless --no-plots, or over one day) the heatmaps written into ``folder``."""
    table.to_csv(folder / DAYS_FILE, index=False, float_format="%.6g")
    written: list[Path | None] = [folder / DAYS_FILE]
    if not args.no_plots and table["day_of_year"].nunique() >= 2:
        from heliostep.plots.sweep import plot_heatmap

        for column, name, label, scale in HEATMAPS:
            written.append(plot_heatmap(table, column, folder / name, label, scale))
    return written


def _print_year(scenario, table, shading: bool) -> None:
    """Each mirror's total over the days, and the field's."""
    columns = ["light_energy_ideal_J", "light_energy_J", "shading_lost_ideal_J"]
    year = table.groupby("mirror_index")[["mirror_distance_m", *columns]].agg(
        {"mirror_distance_m": "first", **{column: "sum" for column in columns}}
    )
    print(
        f"{scenario.name}: {table['day_of_year'].nunique()} days of {scenario.window.date.year}, "
        f"energy on the tube [MJ], ideal two-axis tracking vs the shared primary, "
        + ("with shading and blocking between the mirrors" if shading else "no shading or blocking (--no-shading)")
    )
    rows = list(year.iterrows()) + [("all", year[columns].sum())]
    for index, row in rows:
        ideal, shared, shaded = (row[column] for column in columns)
        lost = 1 - shared / ideal if ideal > 0 else 0.0
        label = f"mirror {index:2d} (d = {row['mirror_distance_m']:+.2f} m)" if index != "all" else "the field      "
        hidden = (
            f", shading and blocking {100 * shaded / (ideal + shaded):4.1f} %" if shading and ideal + shaded > 0 else ""
        )
        energies = f"{ideal / 1e6:9.1f} ideal, {shared / 1e6:9.1f} shared primary"
        print(f"  {label}: {energies} ({100 * lost:5.1f} % lost{hidden})")
