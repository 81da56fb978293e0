"""Where heliostep finds its shipped data and keeps what it builds.

* Modelica models and shipped scenarios: package data of an installed heliostep
  (``heliostep/data/models``, ``heliostep/data/scenarios``), or the checkout's ``models/``
  and ``scenarios/`` for a source (editable) install. ``$HELIOSTEP_MODELS`` points the build
  at another models folder.
* Built FMUs (and other compiled artefacts): a per-user cache folder (platformdirs), or
  ``$HELIOSTEP_FMUS``. Never the source tree. heliostep loads the code the cache holds after checking
  it against a digest kept beside it, so the cache must be the user's alone (:func:`private_cache`).
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from heliostep.errors import InputError

_PACKAGE = Path(__file__).resolve().parent
_CHECKOUT = _PACKAGE.parents[1]


def _shipped(name: str) -> Path:
    installed = _PACKAGE / "data" / name
    return installed if installed.is_dir() else _CHECKOUT / name


def models_dir() -> Path:
    """The folder of Modelica models (``$HELIOSTEP_MODELS`` or the shipped ``models``)."""
    return Path(os.environ.get("HELIOSTEP_MODELS") or _shipped("models"))


def scenarios_dir() -> Path:
    """The folder of the shipped scenarios and their reference traces."""
    return _shipped("scenarios")


def private_cache(folder: Path) -> Path:
    """``folder``, created private to the user (mode 0700) when missing, refused when another user could
    have put code in it: owned by another user, or writable by its group or by all (as ssh refuses such
    key files). A folder that cannot be created is returned as it is (its writer reports why)."""
    try:
        folder.mkdir(mode=0o700, parents=True)
    except FileExistsError:
        pass
    except OSError:
        return folder
    status = folder.stat()
    if status.st_uid != os.geteuid():
        raise InputError(
            f"{folder}: the FMU cache is owned by another user (uid {status.st_uid}), and heliostep loads the code "
            f"it holds; expected your own folder: point HELIOSTEP_FMUS at one, or chown it"
        )
    if status.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        raise InputError(
            f"{folder}: the FMU cache is writable by others (mode {stat.S_IMODE(status.st_mode):03o}), and heliostep "
            f"loads the code it holds; expected a private folder: chmod go-w {folder}"
        )
    return folder


def fmus_dir() -> Path:
    """The folder built FMUs are cached in (``$HELIOSTEP_FMUS`` or the user cache), private to the user
    (:func:`private_cache`)."""
    configured = os.environ.get("HELIOSTEP_FMUS")
    if configured:
        return private_cache(Path(configured))
    from platformdirs import user_cache_path

    return private_cache(user_cache_path("heliostep") / "fmus")
