"""Solar geometry of a linear Fresnel plant with two-axis end mirrors.

Small, pure, vectorised functions in the style of pvlib: angles of the sun in
degrees (as pvlib gives them), mirror and motor angles in radians, lengths in
metres. A :class:`pandas.Series` in gives Series out (functions returning several
components return a tuple of Series).

``[paper]`` in the comments is the source paper of the project's physics notes
(linear Fresnel plant, two-axis end mirrors, stepper drive); ``eq. N`` is its
equation number. See ``docs/geometry.md`` for the equations and conventions.

Frames and conventions
----------------------
* Plant frame: x across the tube, y along the tube, z up. For the default
  North-South plant x = East, y = North. The plant azimuth ``plant_azimuth`` is
  the compass direction of +y, measured from North toward East [deg]: 0 for a
  North-South plant, 90 for an East-West plant (+y = East, +x = South), plus any
  ``azimuth_offset``. The frame stays right-handed for every azimuth.
* The receiver tube is parallel to y, at height ``tube_height`` above the mirror
  plane, over x = 0; a mirror sits at x = ``mirror_distance``.
* Sun: unit vector S toward the sun from pvlib's SPA (``nrel_numpy``). The
  geometry uses the *apparent* (refraction-corrected) elevation throughout,
  because that is the direction from which the light actually arrives.
* End loss k: signed, **positive k means the reflected light lands shifted
  toward +y** (North for a North-South plant), so the first |k| metres at the
  -y end of the tube get no light when k > 0 (and at the +y end when k < 0).
  Its magnitude is [paper] eq. 2.
* Two-axis mirror: n = R_y(primary) R_x(secondary) z_hat, i.e.
  n = (cos q sin p, -sin q, cos q cos p). Both rotations follow the right-hand
  rule: a positive primary tilts the normal toward +x (East for a North-South
  plant), a positive secondary tilts it toward -y. The paper writes eq. 3 with a
  minus sign (its opposite sense for the primary); ours is minus the paper's.
* Stow policy for reference angles (sun at or below ``min_elevation``):
  ``"hold"`` keeps the last valid angle (before the first valid sample, the first
  valid one; with no valid sample in the window at all, ``stow_angle``);
  ``"stow"`` goes to ``stow_angle``. No NaN ever leaves
  :func:`panel_angle_reference`.

Modules: :mod:`~heliostep.solar.sun` (site, plant, SPA), :mod:`~heliostep.solar.tracking`
(tracking laws, reference panel angle), :mod:`~heliostep.solar.transmission` (rotor <-> panel),
:mod:`~heliostep.solar.field` (the end mirrors' field, shared primary),
:mod:`~heliostep.solar.optics` (reflected ray, miss, cosine factor, the point mirror's intercept),
:mod:`~heliostep.solar.intercept` (a finite flat or curved mirror's image on the absorber or a
secondary concentrator), :mod:`~heliostep.solar.shading` (shading and blocking between
neighbouring mirrors), :mod:`~heliostep.solar.receiver_shadow` (the receiver's own shadow),
:mod:`~heliostep.solar.row_shading` (a plant's rows at their tracking attitudes),
:mod:`~heliostep.solar.irradiance` (DNI and wind: pvlib clear sky or a
TMY3/EPW file, hour-ending records), :mod:`~heliostep.solar.endloss` (lit length and energy on the
tube of a plant, single-axis vs two-axis end mirrors, per instant, day and year), and
:mod:`~heliostep.solar.checks`; pvlib's sun grids are kept by content in the FMU cache
(:mod:`~heliostep.solar.sun_cache`: a run seen before does not import pvlib). This package imports
nothing of heliostep but :mod:`heliostep.errors` and :mod:`heliostep.paths` (the cache's folder).
"""

from heliostep.solar.checks import check_timezone
from heliostep.solar.field import (
    DEFAULT_MIRROR_SPACING,
    N_FIELD_MIRRORS,
    field_distances,
    field_primary_errors,
    sharing_errors,
    sharing_figures,
    solar_noon_sun,
)
from heliostep.solar.irradiance import (
    WeatherFile,
    WeatherSeries,
    clear_sky_dni,
    dni,
    read_weather,
    weather_dni,
    weather_series,
)
from heliostep.solar.optics import (
    SUN_HALF_ANGLE,
    cosine_factor,
    end_fraction,
    mirror_normal,
    optical_chain,
    receiver_miss,
    reflect,
)
from heliostep.solar.sun import (
    ORIENTATIONS,
    Plant,
    Site,
    plant_azimuth,
    solar_position,
    sun_events,
    sun_vector,
)
from heliostep.solar.tracking import (
    AXES,
    STOW_POLICIES,
    end_loss_length,
    normal_orientation,
    panel_angle_reference,
    single_axis_tilt,
    time_window,
    two_axis_angles,
    two_axis_angles_from_normal,
    two_axis_normal,
)
from heliostep.solar.transmission import (
    PAPER_LEVER_ARM,
    PAPER_PINION_RADIUS,
    panel_angle_from_rotor,
    rotor_angle_from_panel,
    rotor_speed_from_panel_speed,
)

__all__ = [
    "AXES",
    "DEFAULT_MIRROR_SPACING",
    "N_FIELD_MIRRORS",
    "ORIENTATIONS",
    "PAPER_LEVER_ARM",
    "PAPER_PINION_RADIUS",
    "STOW_POLICIES",
    "Plant",
    "Site",
    "check_timezone",
    "end_loss_length",
    "field_distances",
    "field_primary_errors",
    "normal_orientation",
    "panel_angle_from_rotor",
    "panel_angle_reference",
    "plant_azimuth",
    "rotor_angle_from_panel",
    "rotor_speed_from_panel_speed",
    "sharing_errors",
    "sharing_figures",
    "single_axis_tilt",
    "solar_noon_sun",
    "solar_position",
    "sun_events",
    "sun_vector",
    "time_window",
    "two_axis_angles",
    "two_axis_angles_from_normal",
    "two_axis_normal",
    "SUN_HALF_ANGLE",
    "clear_sky_dni",
    "cosine_factor",
    "dni",
    "end_fraction",
    "mirror_normal",
    "optical_chain",
    "read_weather",
    "receiver_miss",
    "reflect",
    "weather_dni",
    "weather_series",
    "WeatherFile",
    "WeatherSeries",
]
