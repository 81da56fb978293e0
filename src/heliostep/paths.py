"""Where heliostep finds its shipped data and keeps what it builds.

* Modelica models and shipped scenarios: package data of an installed heliostep
  (``heliostep/data/models``, ``heliostep/data/scenarios``), or the checkout's ``models/``
  and ``scenarios/`` for a source (editable) install. ``$HELIOSTEP_MODELS`` points the build
  at another models folder.
* Built FMUs (and other compiled artefacts): a per-user cache folder (platformdirs), or
  ``$HELIOSTEP_FMUS``. Never the source tree.
"""

from __future__ import annotations

import os
from pathlib import Path

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


def fmus_dir() -> Path:
    """The folder built FMUs are cached in (``$HELIOSTEP_FMUS`` or the user cache)."""
    configured = os.environ.get("HELIOSTEP_FMUS")
    if configured:
        return Path(configured)
    from platformdirs import user_cache_path

    return user_cache_path("heliostep") / "fmus"
