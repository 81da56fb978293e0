"""Every PNG heliostep draws is written here: the text without the font's hinting program, zlib's fastest level.

matplotlib's Agg backend renders each glyph through FreeType with the hinting that ``text.hinting``
selects; by default that runs the font's own TrueType bytecode (FreeType's interpreter,
``TT_RunIns``). Without hinting (``"no_hinting"``, the setting matplotlib's own image tests use)
the glyphs keep their outlines' shapes, anti-aliased; the figures' lines, axes and layout are
unchanged, and they are drawn faster (``benchmarks/bench_plots.py``). zlib's level 1 gives the same
pixels in less time than the default level, in slightly larger files. Both apply only while a
figure is written (:func:`save_png`): the caller's ``rcParams`` are left as they were.
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
