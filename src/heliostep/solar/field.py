"""The field of end mirrors across the tube and the error of a primary drive shared by all of them."""

from __future__ import annotations

import functools
import numbers

import numpy as np
import pandas as pd

from heliostep.errors import InputError
from heliostep.solar.checks import as_float_array, check_positive, series_template
from heliostep.solar.sun import Plant, Site, solar_position, sun_events
from heliostep.solar.tracking import two_axis_angles

#: Number of end mirrors in the field; indices run 0 .. N - 1, the central one is N // 2.
N_FIELD_MIRRORS = 13
#: Transverse spacing of the end mirrors [m]. Not from the paper: an assumption.
DEFAULT_MIRROR_SPACING = 0.6


# --------------------------------------------------------------------------- field of end mirrors
def field_distances(n_mirrors: int = N_FIELD_MIRRORS, spacing: float = DEFAULT_MIRROR_SPACING) -> np.ndarray:
    """Transverse positions of the end mirrors, centred on the tube.

    Parameters
    ----------
    n_mirrors : int, default 13
        Odd, so that the central mirror (index (n - 1) / 2) sits under the tube.
    spacing : float, default :data:`DEFAULT_MIRROR_SPACING`  [m]
        > 0.

    Returns
    -------
    numpy.ndarray  [m]
        d_i = (i - (n - 1) / 2) * spacing, i = 0 .. n - 1.
    """
    if isinstance(n_mirrors, bool) or not isinstance(n_mirrors, numbers.Integral) or n_mirrors < 1:
        raise InputError(f"n_mirrors must be an odd integer >= 1, got {n_mirrors!r}")
    if n_mirrors % 2 == 0:
        raise InputError(f"n_mirrors must be odd (a central mirror at d = 0), got {n_mirrors}")
    spacing = check_positive(spacing, "spacing", "m")
    distances = (np.arange(n_mirrors) - (n_mirrors - 1) // 2) * spacing
    return np.round(distances, 12)  # drop the 1e-16 noise of the product, for readable tables


def field_primary_errors(
    elevation,
    azimuth,
    tube_height,
    mirror_distances=None,
    plant_azimuth: float = 0.0,
    calibration=None,
) -> pd.DataFrame:
    """Primary-angle error of each end mirror when all follow the central mirror's law.

    One motor turns every primary by the same angle, so each mirror's primary is its mounting
    offset plus the central mirror's primary. With ``calibration`` the offsets are the ones
    that make every mirror exact when the sun stands there, and the error is the difference
    in *motion* since; without it the error is the plain difference of the angles (the offset
    included).

    Parameters
    ----------
    elevation, azimuth : array-like or Series  [deg]
    tube_height : float  [m]
    mirror_distances : array-like, optional  [m]
        Defaults to :func:`field_distances` ().
    plant_azimuth : float, default 0  [deg]
    calibration : (float, float), optional  [deg]
        Sun elevation and azimuth at which the mirrors are mounted exact (e.g. solar noon).

    Returns
    -------
    pandas.DataFrame  [rad]
        Own primary minus the central (d = 0) primary, minus the same at the calibration;
        one column per mirror distance, indexed like ``elevation`` (if a Series).
    """
    if mirror_distances is None:
        mirror_distances = field_distances()
    distances = as_float_array(mirror_distances).ravel()
    elevation_values = np.atleast_1d(as_float_array(elevation))
    azimuth_values = np.atleast_1d(as_float_array(azimuth))

    def own_minus_central(sun_elevation, sun_azimuth):
        central, _ = two_axis_angles(sun_elevation, sun_azimuth, 0.0, tube_height, plant_azimuth)
        own, _ = two_axis_angles(
            sun_elevation[:, None], sun_azimuth[:, None], distances[None, :], tube_height, plant_azimuth
        )
        return own - central[:, None]

    errors = own_minus_central(elevation_values, azimuth_values)
    if calibration is not None:
        offsets = own_minus_central(np.atleast_1d(float(calibration[0])), np.atleast_1d(float(calibration[1])))
        errors = errors - offsets
    template = series_template(elevation, azimuth)
    index = template.index if template is not None else None
    return pd.DataFrame(
        errors,
        index=index,
        columns=pd.Index(distances, name="mirror_distance"),
    )


@functools.lru_cache(maxsize=64)
def solar_noon_sun(date, site: Site) -> tuple[float, float]:
    """Sun (apparent elevation, azimuth) [deg] at solar noon (transit) of a local date at the site.

    Remembered per (date, site): a run's light figures, taken block by block, ask for it once
    per block."""
    transit = sun_events(date, site)["transit"]
    sun = solar_position(pd.DatetimeIndex([transit]), site.latitude, site.longitude, site.altitude)
    return float(sun["apparent_elevation"].iloc[0]), float(sun["azimuth"].iloc[0])


def sharing_errors(
    times: pd.DatetimeIndex, site: Site, plant: Plant, date, mirror_distances, sun: pd.DataFrame | None = None
) -> np.ndarray:
    """Primary sharing errors [rad] at ``times``, one column per mirror distance; NaN while the sun is down.

    Every primary turns by the central mirror's angle; each mirror is mounted with the offset
    that makes it exact at solar noon of ``date`` (:func:`field_primary_errors` with that
    calibration). ``sun``: :func:`solar_position` at ``times`` already computed (else computed here).
    """
    if sun is None:
        sun = solar_position(times, site.latitude, site.longitude, site.altitude)
    elevation = sun["apparent_elevation"].to_numpy()
    errors = (
        field_primary_errors(
            elevation,
            sun["azimuth"].to_numpy(),
            plant.tube_height,
            mirror_distances,
            plant.azimuth,
            calibration=solar_noon_sun(date, site),
        )
        .to_numpy()
        .copy()
    )
    errors[elevation <= 0.0, :] = np.nan
    return errors


def sharing_figures(errors: np.ndarray) -> dict:
    """Max |error| and the signed error at that instant [deg] of one mirror's error column [rad]."""
    finite = np.isfinite(errors)
    if not finite.any():
        return {"primary_sharing_error_max_deg": None, "primary_sharing_error_signed_deg": None}
    degrees = np.degrees(np.where(finite, errors, 0.0))
    worst = int(np.argmax(np.abs(degrees)))
    return {
        "primary_sharing_error_max_deg": float(abs(degrees[worst])),
        "primary_sharing_error_signed_deg": float(degrees[worst]),
    }


# --------------------------------------------------------------------------- the shared primary's load
#: The panel of Table 2 [paper]: mass [kg], density [kg/m3], length along the tube [m], thickness [m].
PANEL_MASS, PANEL_DENSITY, PANEL_LENGTH, PANEL_THICKNESS = 18.0, 800.0, 1.5, 0.05
#: Panel width across the tube [m]: what Table 2's mass, density, length and thickness leave,
#: M / (rho l sp) = 0.3 m (the paper gives no width; this follows from its other values).
PANEL_WIDTH = PANEL_MASS / (PANEL_DENSITY * PANEL_LENGTH * PANEL_THICKNESS)
#: Lever arm of the primary's rack on each panel [m]: an assumption, the rack at the panel's edge
#: (half its width, the longest arm the panel offers); the paper does not describe the primary drive.
PRIMARY_LEVER_ARM = PANEL_WIDTH / 2


def primary_panel_inertia(n_mirrors: int = N_FIELD_MIRRORS) -> float:
    """Inertia of the panels a shared primary drive turns about their longitudinal axes [kg m2].

    Each panel turns about its own axis along the tube: M/12 (w² + sp²) (the rectangular plate
    of [paper] eq. 11, about the other axis), all ``n_mirrors`` linked to one motor.
    """
    return n_mirrors * PANEL_MASS / 12.0 * (PANEL_WIDTH**2 + PANEL_THICKNESS**2)  # [paper], eq. 11
