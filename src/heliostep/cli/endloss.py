"""``heliostep end-loss``: lit length and energy on the tube, single-axis plant vs two-axis end mirrors.

Details: docs/light.md, ``heliostep.cli.endloss``.
"""

from __future__ import annotations

import argparse
import datetime as dt
from pathlib import Path

from heliostep.errors import InputError
from heliostep.progress import progress_bar
from heliostep.results.output.files import check_out_name
from heliostep.results.output.folder import owned_folder, write_swapped
from heliostep.scenario.model import FIRST_YEAR, LAST_YEAR, window_date_problem
from heliostep.solar import field_distances
from heliostep.solar.endloss import end_loss_days, largest_shift
from heliostep.solar.field import DEFAULT_MIRROR_SPACING, PANEL_LENGTH, PANEL_WIDTH
from heliostep.solar.optics import optical_chain
from heliostep.solar.sun import Site

#: The table of the days (with the year's figure, plots.endloss.END_LOSS_FILE, the files the command writes).
DAYS_FILE = "end_loss_days.csv"


def register(subparsers) -> argparse.ArgumentParser:
    """Add the ``end-loss`` command."""
    parser = subparsers.add_parser(
        "end-loss",
        help="end-loss gain of two-axis end mirrors: lit length and energy per day and year",
        description=__doc__.split("\n\n", 1)[0],
    )
    parser.add_argument("--latitude", type=float, default=40.0, help="[deg], +North (default 40, the paper's)")
    parser.add_argument("--longitude", type=float, default=14.25, help="[deg], +East (default 14.25, assumed)")
    parser.add_argument("--altitude", type=float, default=0.0, help="[m] (default 0)")
    parser.add_argument("--timezone", default="Europe/Rome", help="IANA name (default Europe/Rome, assumed)")
    parser.add_argument("--year", type=int, default=2025, help="(default 2025)")
    parser.add_argument("--days", type=int, nargs="+", help="days of the year (default all)")
    parser.add_argument("--length", type=float, default=100.0, help="[m] plant and tube length L (default 100)")
    parser.add_argument("--tube-height", type=float, default=5.0, help="[m] h (default 5, the paper's)")
    parser.add_argument("--rows", type=int, default=13, help="rows of mirrors across, odd (default 13)")
    spacing = f"[m] between rows (default {DEFAULT_MIRROR_SPACING:g}, the scenarios' field, assumed)"
    parser.add_argument("--spacing", type=float, default=DEFAULT_MIRROR_SPACING, help=spacing)
    width = f"[m] of each row (default {PANEL_WIDTH:.2g}, Table 2's panel, as the scenarios' mirrors)"
    parser.add_argument("--mirror-width", type=float, default=PANEL_WIDTH, help=width)
    parser.add_argument(
        "--end-length",
        type=float,
        help="[m] of each two-axis end section (default: the year's largest k above 5 deg sun elevation)",
    )
    parser.add_argument(
        "--mirror-length",
        type=float,
        default=PANEL_LENGTH,
        help=f"[m] of each two-axis end mirror along the row, contiguous (default {PANEL_LENGTH:g}, Table 2's panel)",
    )
    parser.add_argument(
        "--no-shading", action="store_true", help="ignore shading and blocking between neighbours (the old model)"
    )
    parser.add_argument(
        "--shading-step-minutes",
        type=float,
        default=30.0,
        help="[min] step of the shading and blocking losses, interpolated between (default 30)",
    )
    parser.add_argument(
        "--receiver-width",
        type=float,
        default=0.07,
        help="[m] of the receiver across, its own shadow on the rows (default 0.07, the scenarios' bare 70 mm "
        "absorber; a secondary's aperture width with one; 0: no receiver shadow)",
    )
    parser.add_argument("--reflectivity", type=float, default=0.80, help="rho (default 0.80, seed 004)")
    parser.add_argument("--transmittance", type=float, default=0.85, help="tau (default 0.85)")
    parser.add_argument("--absorptance", type=float, default=0.95, help="alpha (default 0.95)")
    parser.add_argument("--step-minutes", type=float, default=5.0, help="[min] time step (default 5)")
    parser.add_argument("--out", default="end-loss-out", help="output folder (default end-loss-out)")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG")
    parser.set_defaults(func=_end_loss_command)
    return parser


def _checked_options(args: argparse.Namespace) -> None:
    """The options end_loss_days does not check itself: the year, the section's and the receiver's sizes."""
    if not FIRST_YEAR <= args.year <= LAST_YEAR:
        raise InputError(f"--year {args.year}: expected a year from {FIRST_YEAR} to {LAST_YEAR} (pandas' timestamps)")
    problem = window_date_problem(dt.date(args.year, 1, 1), args.timezone)
    if problem:
        raise InputError(f"--year {args.year}: {problem}")
    if not (args.mirror_length > 0 and args.shading_step_minutes > 0):
        raise InputError("--mirror-length and --shading-step-minutes: expected > 0 [m], [min]")
    if not args.receiver_width >= 0:
        raise InputError(f"--receiver-width {args.receiver_width!r}: expected >= 0 [m] (0: no receiver shadow)")


def _end_loss_command(args: argparse.Namespace) -> int:
    _checked_options(args)
    out = check_out_name(args.out)
    site = Site(latitude=args.latitude, longitude=args.longitude, altitude=args.altitude, timezone=args.timezone)
    distances = field_distances(args.rows, args.spacing)
    width = args.mirror_width
    efficiency = optical_chain(args.reflectivity, args.transmittance, args.absorptance)
    end = args.end_length
    if end is None:
        end = largest_shift(site, args.year, args.tube_height, distances)
    if not 2 * end < args.length:
        raise InputError(f"--end-length {end:.3g} m: two end sections must be shorter than --length {args.length:g} m")
    from heliostep.plots.endloss import END_LOSS_FILE

    n_days = len(set(args.days)) if args.days else (dt.date(args.year + 1, 1, 1) - dt.date(args.year, 1, 1)).days
    with (
        owned_folder(out, (DAYS_FILE, END_LOSS_FILE)),  # the folder's lock for the command's life
        progress_bar(n_days, "end loss", "day") as bar,
    ):
        days = end_loss_days(
            site,
            args.year,
            args.length,
            args.tube_height,
            distances,
            width,
            end,
            efficiency,
            days=args.days,
            step_minutes=args.step_minutes,
            mirror_length=args.mirror_length,
            shading=not args.no_shading,
            shading_step_minutes=args.shading_step_minutes,
            receiver_width=args.receiver_width or None,
            progress=bar.update,
        )
        written = list(write_swapped(out, lambda staging: _write_days(args, days, staging)).values())
    _print_totals(args, days, end, width)
    for path in written:
        print(f"  wrote {path}")
    return 0


def _write_days(args: argparse.Namespace, days, folder: Path) -> list[Path | None]:
    """The table and (unless --no-plots) the year's figure written into ``folder``."""
    days.to_csv(folder / DAYS_FILE, float_format="%.6g")
    if args.no_plots:
        return [folder / DAYS_FILE]
    from heliostep.plots.endloss import END_LOSS_FILE, plot_end_loss_year

    title = f"\n{args.length:g} m plant, h = {args.tube_height:g} m, {args.rows} rows, {args.latitude:g} deg N"
    return [folder / DAYS_FILE, plot_end_loss_year(days, folder / END_LOSS_FILE, title)]


def _print_totals(args: argparse.Namespace, days, end: float, width: float) -> None:
    """The year's totals and the 21 December figures, on stdout."""
    single, two = days["energy_single_J"].sum(), days["energy_two_axis_J"].sum()
    print(f"end sections of two-axis mirrors: {end:.2f} m at each end; {len(days)} days of {args.year}")
    shading = "none (--no-shading)" if args.no_shading else f"rows {width:g} m wide at {args.spacing:g} m"
    print(f"  shading and blocking between neighbours: {shading}")
    print(f"  energy on the tube, single-axis plant   {single / 3.6e9:10.2f} MWh")
    print(
        f"  energy on the tube, two-axis end mirrors {two / 3.6e9:10.2f} MWh  (gain {100 * (two / single - 1):.2f} %)"
    )
    december = dt.date(args.year, 12, 21).timetuple().tm_yday
    if december in days.index:
        row = days.loc[december]
        print(
            f"  21 December: dark length at noon {row['unlit_length_noon_m']:.2f} m, "
            f"lit {row['lit_length_noon_m']:.2f} m; gain {100 * row['gain_noon']:.1f} % at noon, "
            f"{100 * row['gain']:.1f} % over the day"
        )
