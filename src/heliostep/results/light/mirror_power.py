"""Power on the tube of one mirror at a given attitude: the one formula every light figure uses.

Details: docs/light.md, ``heliostep.results.light.mirror_power``.
"""

from __future__ import annotations

import numpy as np

from heliostep.solar import optics
from heliostep.solar.intercept import intercept
from heliostep.solar.receiver_shadow import receiver_shadow_fraction, receiver_width

__all__ = ["IMAGE_KEYS", "attitude_light", "receiver_image"]


#: What :func:`attitude_light` takes from its ``image`` argument instead of computing it.
IMAGE_KEYS = ("intercept", "transverse_miss_m", "longitudinal_miss_m")


def attitude_light(
    sun, dni, up, primary, secondary, distance: float, tube_height: float, conf, receiver_shadow=True, image=None
) -> dict:
    """Power on the tube of a mirror at one attitude, at each instant.

    Parameters
    ----------
    sun : array (3, n)  [-]
        Unit vector to the sun in the plant frame.
    dni : array (n,)  [W/m^2]
    up : array of bool (n,)
        The sun above the horizon.
    primary, secondary : arrays (n,)  [rad]
        The mirror's two angles (:func:`heliostep.solar.optics.mirror_normal`).
    distance, tube_height : float  [m]
    conf : heliostep.scenario.OpticsConfig
    receiver_shadow : bool, default True
        The receiver's own shadow on the mirror (False: a caller that unites it with the neighbours'
        shadows itself, :func:`heliostep.solar.shading.row_losses`).
    image : dict of arrays (n,), optional
        :func:`receiver_image`'s :data:`IMAGE_KEYS` computed elsewhere (from the sun grid,
        :mod:`heliostep.results.light.sun_grid_image`); None: computed here.

    Returns
    -------
    dict of arrays
        ``power_W`` = DNI A cos (1 - s_r) rho tau alpha gamma f_end [W], ``intercept`` (gamma),
        ``cosine``, ``receiver_shadow`` (s_r; 0 with ``receiver_shadow`` False), ``end_fraction``
        (f_end, the share of the mirror's light that lands on the tube's length,
        :func:`heliostep.solar.optics.end_fraction`; 1 without ``tube_ends``) [-],
        ``transverse_miss_m``, ``longitudinal_miss_m`` [m].
    """
    chain = optics.optical_chain(conf.reflectivity, conf.transmittance, conf.absorptance)
    normal = optics.mirror_normal(primary, secondary)
    cosine = optics.cosine_factor(*sun, *normal)
    receiver = conf.receiver()
    if image is None:
        image = _image(sun, primary, secondary, normal, distance, tube_height, receiver, conf)
    gamma, transverse, longitudinal = (image[key] for key in IMAGE_KEYS)
    on_tube = (
        np.ones_like(gamma)
        if conf.tube_ends is None
        # the end effect: light past the tube's end
        else optics.end_fraction(longitudinal, conf.mirror_length, 0.0, *conf.tube_ends)
    )
    shadow = (
        _own_shadow(sun, normal, distance, tube_height, conf, receiver) if receiver_shadow else np.zeros_like(gamma)
    )
    power = np.where(up, dni * conf.aperture_area * cosine * (1.0 - shadow) * chain * gamma * on_tube, 0.0)
    return {
        "power_W": power,
        "intercept": gamma,
        "cosine": cosine,
        "receiver_shadow": shadow,
        "end_fraction": on_tube,
        "transverse_miss_m": transverse,
        "longitudinal_miss_m": longitudinal,
    }


def receiver_image(sun, primary, secondary, distance: float, tube_height: float, conf) -> dict:
    """The finite mirror's image on the receiver (tube or secondary) at each instant:
    :data:`IMAGE_KEYS` of :func:`heliostep.solar.intercept.intercept` (the arguments as
    :func:`attitude_light`'s)."""
    normal = optics.mirror_normal(primary, secondary)
    return _image(sun, primary, secondary, normal, distance, tube_height, conf.receiver(), conf)


def _image(sun, primary, secondary, normal, distance: float, tube_height: float, receiver: dict, conf) -> dict:
    """:func:`receiver_image` with the mirror's normal and ``conf.receiver()`` already computed."""
    ray = optics.reflect(*sun, *normal)
    caught = intercept(sun, primary, secondary, ray, distance, tube_height, receiver, conf.mirror())
    return {key: caught[key] for key in IMAGE_KEYS}


def _own_shadow(sun, normal, distance: float, tube_height: float, conf, receiver: dict) -> np.ndarray:
    """The share of the mirror in the receiver's shadow [-], sun (3, n) and normal (3 arrays of n)."""
    width = receiver_width(receiver["tube_diameter"], receiver["secondary"])
    sun_rows = np.moveaxis(np.asarray(sun, dtype=float), 0, -1)
    normals = np.stack(np.broadcast_arrays(*normal), axis=-1)
    return receiver_shadow_fraction(
        sun_rows, normals, distance, tube_height, width, conf.mirror_width, conf.mirror_length
    )
