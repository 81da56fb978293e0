"""``heliostep geometry``: solar geometry tables and plots.

Details: docs/geometry.md, ``heliostep.cli.geometry``.
"""

from __future__ import annotations

import argparse
import datetime as dt
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep import solar as geometry
from heliostep.errors import InputError
from heliostep.results.output.files import check_out_name
from heliostep.results.output.folder import owned_folder, write_swapped
from heliostep.scenario.model import window_date_problem

DEFAULT_DATES = ("2025-12-21", "2025-01-21", "2025-03-21", "2025-06-21")
PAPER_DATE = "2025-01-21"
PAPER_TUBE_HEIGHT = 3.0  # [m]
PAPER_LATITUDE = 40.0  # [deg]
ASSUMED_LONGITUDE = 14.25  # [deg] assumption
ASSUMED_TIMEZONE = "Europe/Rome"  # assumption
#: Every file the command may write into --out (a rerun replaces only those, listed in its manifest).
GEOMETRY_FILES = (
    "end_loss.csv",
    "two_axis_angles.csv",
    "end_loss.png",
    "two_axis_angles.png",
    "paper_case.csv",
    "paper_case_panel_angle.png",
    "paper_case_rotor_angle.png",
)


def register(subparsers) -> argparse.ArgumentParser:
    """Add the ``geometry`` command to an argparse subparsers object."""
    parser = subparsers.add_parser(
        "geometry",
        help="solar geometry: end loss, two-axis mirror angles, the paper's reference case",
        description=__doc__.split("\n\n", 1)[0],
    )
    _add_site_and_day_options(parser)
    _add_plant_and_mirror_options(parser)
    _add_paper_case_options(parser)
    parser.add_argument("--out", default="geometry-out", help="output directory (default geometry-out)")
    parser.set_defaults(func=run)
    return parser


def _add_site_and_day_options(parser: argparse.ArgumentParser) -> None:
    site = parser.add_argument_group("site")
    site.add_argument("--latitude", type=float, default=PAPER_LATITUDE, help="[deg], +North (default 40)")
    site.add_argument(
        "--longitude", type=float, default=ASSUMED_LONGITUDE, help="[deg], +East (default 14.25, assumed)"
    )
    site.add_argument("--altitude", type=float, default=0.0, help="[m] above sea level (default 0)")
    site.add_argument("--timezone", default=ASSUMED_TIMEZONE, help="IANA name (default Europe/Rome, assumed)")
    days = parser.add_argument_group("days")
    days.add_argument(
        "--date",
        action="append",
        metavar="YYYY-MM-DD",
        help="day to tabulate; repeatable (default: " + ", ".join(DEFAULT_DATES) + ")",
    )
    days.add_argument("--step", type=float, default=60.0, help="time step of the day tables [s] (default 60)")


def _add_plant_and_mirror_options(parser: argparse.ArgumentParser) -> None:
    plant = parser.add_argument_group("plant")
    plant.add_argument("--orientation", default="NS", help="tube direction: NS or EW (default NS)")
    plant.add_argument("--azimuth-offset", type=float, default=0.0, help="extra tube azimuth, North toward East [deg]")
    plant.add_argument("--tube-height", type=float, default=5.0, help="receiver height h [m] (default 5)")
    mirrors = parser.add_argument_group("mirrors")
    mirrors.add_argument(
        "--mirror-distance", type=float, action="append", metavar="D", help="transverse position d [m]; repeatable"
    )
    mirrors.add_argument(
        "--mirror",
        type=int,
        action="append",
        metavar="INDEX",
        help="index 0..12 of the 13-mirror end field (6 = central); repeatable",
    )
    mirrors.add_argument(
        "--spacing",
        type=float,
        default=geometry.DEFAULT_MIRROR_SPACING,
        help=f"transverse spacing of the field [m] (default {geometry.DEFAULT_MIRROR_SPACING:g}, assumed)",
    )


def _add_paper_case_options(parser: argparse.ArgumentParser) -> None:
    paper = parser.add_argument_group("the paper's case (Figs. 8 and 9)")
    paper.add_argument("--paper-case", action="store_true", help="also write the paper's reference case")
    paper.add_argument("--paper-date", default=PAPER_DATE, help=f"day of the case (default {PAPER_DATE})")
    paper.add_argument("--window-start", default="10:00", metavar="HH:MM", help="local clock time (default 10:00)")
    paper.add_argument("--window-minutes", type=float, default=5.0, help="window length [min] (default 5)")
    paper.add_argument("--window-step", type=float, default=1.0, help="time step in the window [s] (default 1)")
    paper.add_argument(
        "--pinion-radius", type=float, default=geometry.PAPER_PINION_RADIUS, help="r [m] (default 0.0025)"
    )
    paper.add_argument("--lever-arm", type=float, default=geometry.PAPER_LEVER_ARM, help="s [m] (default 0.3)")
    paper.add_argument("--stow", default="hold", help="policy with the sun down: hold or stow (default hold)")
    paper.add_argument("--stow-angle", type=float, default=0.0, help="stow panel angle [deg] (default 0)")


# --------------------------------------------------------------------------- parsing
def _parse_date(text: str, option: str, timezone: str) -> dt.date:
    try:
        date = dt.date.fromisoformat(text)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{option} must be an ISO date YYYY-MM-DD, got {text!r}") from exc
    problem = window_date_problem(date, timezone)
    if problem:
        raise InputError(f"{option} {problem}")
    return date


#: The most rows the day tables or the paper window may have (about a gigabyte).
MAX_TABLE_ROWS = 5_000_000


def _check_rows(rows: float, option: str, step: float, what: str) -> None:
    """Refuse a time step that would make more than :data:`MAX_TABLE_ROWS` rows, before any is made."""
    if rows > MAX_TABLE_ROWS:
        raise InputError(
            f"{option} {step:g} s: {what} would have an estimated {rows:.3g} rows, over {MAX_TABLE_ROWS:.0e}; "
            f"expected a step of at least {step * rows / MAX_TABLE_ROWS:.3g} s"
        )


def _parse_clock(text: str, option: str) -> dt.time:
    try:
        clock = dt.time.fromisoformat(text)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{option} must be a local clock time HH:MM, got {text!r}") from exc
    if clock.tzinfo is not None:
        raise InputError(f"{option} must be a local clock time without offset, got {text!r}")
    return clock


def _positive(value: float, option: str, unit: str) -> float:
    if not np.isfinite(value) or value <= 0:
        raise InputError(f"{option} must be > 0 {unit}, got {value:g}")
    return value


def _choice(value: str, option: str, allowed) -> str:
    if value not in allowed:
        raise InputError(f"{option} must be one of {', '.join(allowed)}, got {value!r}")
    return value


def _mirror_distances(args) -> list[float]:
    distances = list(args.mirror_distance or [])
    if args.mirror:
        field = geometry.field_distances(13, args.spacing)
        for index in args.mirror:
            if not 0 <= index < len(field):
                raise InputError(f"--mirror must be within [0, {len(field) - 1}], got {index}")
            distances.append(float(field[index]))
    return list(dict.fromkeys(distances or [0.0]))


def _day_times(date: dt.date, timezone: str, step_seconds: float) -> pd.DatetimeIndex:
    start = pd.Timestamp(date).tz_localize(timezone)
    end = (pd.Timestamp(date) + pd.Timedelta(days=1)).tz_localize(timezone)
    return pd.date_range(start, end, freq=pd.Timedelta(seconds=step_seconds), inclusive="left")


def _local_hours(times: pd.DatetimeIndex) -> np.ndarray:
    naive = times.tz_localize(None)
    return ((naive - naive.normalize()) / pd.Timedelta(hours=1)).to_numpy()


# --------------------------------------------------------------------------- tables
def day_tables(site: geometry.Site, plant: geometry.Plant, dates, distances, step_seconds):
    """End-loss and two-axis tables over the daylight of each date.

    Returns
    -------
    end_loss, two_axis : pandas.DataFrame
        Long tables, one row per (date, time, mirror distance).
    """
    end_loss_rows, two_axis_rows = [], []
    for date in dates:
        times = _day_times(date, site.timezone, step_seconds)
        position = geometry.solar_position(times, site.latitude, site.longitude, site.altitude)
        day = position[position["apparent_elevation"] > 0.0]
        if day.empty:
            continue
        elevation, azimuth = day["apparent_elevation"], day["azimuth"]
        common = {
            "time_local": day.index.strftime("%Y-%m-%dT%H:%M:%S%z"),
            "date": date.isoformat(),
            "hour_local": _local_hours(day.index),
            "apparent_elevation_deg": elevation.to_numpy(),
            "azimuth_deg": azimuth.to_numpy(),
        }
        central_primary, _ = geometry.two_axis_angles(elevation, azimuth, 0.0, plant.tube_height, plant.azimuth)
        for distance in distances:
            end_loss = geometry.end_loss_length(elevation, azimuth, distance, plant.tube_height, plant.azimuth)
            tilt = geometry.single_axis_tilt(elevation, azimuth, distance, plant.tube_height, plant.azimuth)
            end_loss_rows.append(
                pd.DataFrame(
                    {
                        **common,
                        "mirror_distance_m": distance,
                        "single_axis_tilt_deg": np.degrees(tilt.to_numpy()),
                        "end_loss_m": end_loss.to_numpy(),
                    }
                )
            )
            primary, secondary = geometry.two_axis_angles(
                elevation, azimuth, distance, plant.tube_height, plant.azimuth
            )
            two_axis_rows.append(
                pd.DataFrame(
                    {
                        **common,
                        "mirror_distance_m": distance,
                        "primary_deg": np.degrees(primary.to_numpy()),
                        "secondary_deg": np.degrees(secondary.to_numpy()),
                        "primary_error_deg": np.degrees((primary - central_primary).to_numpy()),
                    }
                )
            )
    if not end_loss_rows:
        raise InputError("--date: the sun never rises above the horizon on the chosen dates at this site")
    return pd.concat(end_loss_rows, ignore_index=True), pd.concat(two_axis_rows, ignore_index=True)


def paper_case_table(
    site: geometry.Site,
    date: dt.date,
    window_start: dt.time,
    window_minutes: float,
    window_step: float,
    pinion_radius: float,
    lever_arm: float,
    stow: str = "hold",
    stow_angle: float = 0.0,
) -> pd.DataFrame:
    """The paper's reference case: central mirror, secondary axis, h = 3 m.

    Returns
    -------
    pandas.DataFrame
        Indexed by the window's times: reference panel angle, rotor angle (0 at the
        window start) and rotor speed, in degrees and degrees per second.
    """
    start = pd.Timestamp(dt.datetime.combine(date, window_start))
    times = geometry.time_window(
        start,
        start + pd.Timedelta(minutes=window_minutes),
        freq=pd.Timedelta(seconds=window_step),
        timezone=site.timezone,
    )
    plant = geometry.Plant(tube_height=PAPER_TUBE_HEIGHT)
    panel_angle_ref = geometry.panel_angle_reference(
        times, site, plant, 0.0, axis="secondary", stow=stow, stow_angle=stow_angle
    )
    rotor_angle_ref = geometry.rotor_angle_from_panel(
        panel_angle_ref, panel_angle_ref.iloc[0], pinion_radius, lever_arm, rotor_angle0=0.0
    )
    elapsed = (times - times[0]) / pd.Timedelta(seconds=1)
    panel_speed = np.gradient(panel_angle_ref.to_numpy(), elapsed.to_numpy()) if len(times) > 1 else np.zeros(1)
    rotor_speed = geometry.rotor_speed_from_panel_speed(panel_angle_ref, panel_speed, pinion_radius, lever_arm)
    position = geometry.solar_position(times, site.latitude, site.longitude, site.altitude)
    return pd.DataFrame(
        {
            "time_local": times.strftime("%Y-%m-%dT%H:%M:%S%z"),
            "elapsed_s": elapsed.to_numpy(),
            "apparent_elevation_deg": position["apparent_elevation"].to_numpy(),
            "azimuth_deg": position["azimuth"].to_numpy(),
            "panel_angle_ref_deg": np.degrees(panel_angle_ref.to_numpy()),
            "rotor_angle_ref_deg": np.degrees(rotor_angle_ref.to_numpy()),
            "rotor_speed_ref_deg_s": np.degrees(rotor_speed.to_numpy()),
        },
        index=times,
    )


# --------------------------------------------------------------------------- command
def run(args) -> int:
    """Run ``heliostep geometry`` with parsed arguments; returns the exit status."""
    site = geometry.Site(
        latitude=args.latitude, longitude=args.longitude, altitude=args.altitude, timezone=args.timezone
    )
    plant = geometry.Plant(
        tube_height=args.tube_height, orientation=args.orientation, azimuth_offset=args.azimuth_offset
    )
    dates = [_parse_date(text, "--date", args.timezone) for text in (args.date or DEFAULT_DATES)]
    step = _positive(args.step, "--step", "s")
    distances = _mirror_distances(args)
    _check_rows(len(dates) * 86400.0 / step * len(distances), "--step", step, "the day tables")
    paper_inputs = _paper_case_inputs(args) if args.paper_case else None

    # matplotlib only once the inputs are known to be good
    from heliostep.plots import geometry as plots

    out = check_out_name(args.out)
    with owned_folder(out, GEOMETRY_FILES):  # the folder's lock for the command's life
        end_loss, two_axis = day_tables(site, plant, dates, distances, step)

        def write(staging: Path) -> list[Path]:
            end_loss.to_csv(staging / "end_loss.csv", index=False)
            two_axis.to_csv(staging / "two_axis_angles.csv", index=False)
            files = [staging / "end_loss.csv", staging / "two_axis_angles.csv"]
            files.append(plots.plot_end_loss(end_loss, staging / "end_loss.png", site.timezone, plant.tube_height))
            files.append(plots.plot_two_axis_angles(two_axis, staging / "two_axis_angles.png", site.timezone))
            if paper_inputs is not None:
                files += _write_paper_case(plots, site, paper_inputs, staging)
            return files

        written = list(write_swapped(out, write).values())
    for path in written:
        print(f"wrote {path}")
    return 0


def _paper_case_inputs(args) -> dict:
    """The keyword arguments of :func:`paper_case_table` from the ``--paper-*``/``--window-*`` options."""
    minutes = _positive(args.window_minutes, "--window-minutes", "min (empty window)")
    step = _positive(args.window_step, "--window-step", "s")
    _check_rows(minutes * 60.0 / step, "--window-step", step, "the paper's window")
    return dict(
        date=_parse_date(args.paper_date, "--paper-date", args.timezone),
        window_start=_parse_clock(args.window_start, "--window-start"),
        window_minutes=minutes,
        window_step=step,
        pinion_radius=_positive(args.pinion_radius, "--pinion-radius", "m"),
        lever_arm=_positive(args.lever_arm, "--lever-arm", "m"),
        stow=_choice(args.stow, "--stow", geometry.STOW_POLICIES),
        stow_angle=float(np.radians(args.stow_angle)),
    )


def _write_paper_case(plots, site: geometry.Site, paper_inputs: dict, out: Path) -> list[Path]:
    """Write the paper's case (table and Figs. 8, 9) to *out*, print its angles; returns the files."""
    written: list[Path] = []
    table = paper_case_table(site, **paper_inputs)
    table.to_csv(out / "paper_case.csv", index=False)
    written.append(out / "paper_case.csv")
    where = f"{site.latitude:g}° lat, h = {PAPER_TUBE_HEIGHT:g} m, d = 0"
    written.append(
        plots.plot_panel_angle_reference(
            table.index,
            table["panel_angle_ref_deg"],
            out / "paper_case_panel_angle.png",
            site.timezone,
            f"Reference secondary panel angle, {paper_inputs['date']} ({where})",
        )
    )
    written.append(
        plots.plot_rotor_angle_reference(
            table.index,
            table["rotor_angle_ref_deg"],
            out / "paper_case_rotor_angle.png",
            site.timezone,
            f"Reference rotor angle from 0, r = {paper_inputs['pinion_radius'] * 1e3:g} mm, "
            f"s = {paper_inputs['lever_arm']:g} m",
        )
    )
    first, last = table.iloc[0], table.iloc[-1]
    print(
        f"paper case: panel angle {first.panel_angle_ref_deg:.4f}° -> {last.panel_angle_ref_deg:.4f}°, "
        f"rotor angle 0° -> {last.rotor_angle_ref_deg:.3f}°"
    )
    return written
