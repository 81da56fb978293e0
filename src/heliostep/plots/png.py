"""Every PNG heliostep draws is written here: the text without the font's hinting program, zlib's fastest level.

Details: docs/running.md, ``heliostep.plots.png``.
"""

from __future__ import annotations

from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import matplotlib
from matplotlib.figure import Figure

if TYPE_CHECKING:
    from matplotlib.typing import RcKeyType

__all__ = ["PNG_OPTIONS", "RENDERING", "save_png"]

#: zlib's fastest level for the PNGs: the same pixels, files about 15 % larger, a third of the encoding's time.
PNG_OPTIONS = {"compress_level": 1}
#: The rcParams set while a PNG is written.
RENDERING: dict[RcKeyType, Any] = {"text.hinting": "no_hinting"}


def save_png(figure: Figure, target: str | Path | IO[bytes], dpi: float, **options) -> None:
    """Write ``figure`` as a PNG to ``target`` (a path or a binary file) at ``dpi`` [dots per inch],
    with :data:`RENDERING` and :data:`PNG_OPTIONS`; ``options`` go to ``savefig`` (e.g. ``bbox_inches``)."""
    with matplotlib.rc_context(RENDERING):
        figure.savefig(target, format="png", dpi=dpi, pil_kwargs=PNG_OPTIONS, **options)
