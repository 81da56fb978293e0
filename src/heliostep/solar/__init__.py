"""Solar geometry of a linear Fresnel plant with two-axis end mirrors.

Small, pure, vectorised functions in the style of pvlib: sun angles in degrees, mirror and motor
angles in radians, lengths in metres; a Series in gives Series out. ``[paper], eq. N`` in the
comments is the source paper's equation. Frames and conventions: docs/geometry.md.

Details: docs/geometry.md, ``heliostep.solar``.
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
    clear_sky_irradiance,
    cloud_fraction,
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
    "clear_sky_irradiance",
    "cloud_fraction",
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
