"""heliostep.plots.png: every PNG written without the font's hinting, the caller's rcParams untouched."""

from __future__ import annotations

import io

import matplotlib
import numpy as np
import pytest
from matplotlib.figure import Figure
from PIL import Image

from heliostep.plots.png import PNG_OPTIONS, RENDERING, save_png


def _figure() -> Figure:
    fig = Figure(figsize=(4.0, 2.0))
    ax = fig.add_subplot()
    ax.plot([0.0, 1.0, 2.0], [0.0, 1.0, 0.5])
    ax.set_title("Fig. 8: panel angle reference (jan21-central, 2025-01-21)")
    ax.set_xlabel("local time (Europe/Rome) [hh:mm:ss]")
    return fig


def _pixels(png: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGBA"))


def _zlib_header(png: bytes) -> bytes:
    start = png.index(b"IDAT") + 4  # the first image data chunk's data: a zlib stream
    return png[start : start + 2]


def _saved(**rc) -> bytes:
    buffer = io.BytesIO()
    with matplotlib.rc_context(rc):
        _figure().savefig(buffer, format="png", dpi=120)
    return buffer.getvalue()


def test_the_png_has_the_text_drawn_without_hinting_and_the_same_pixels_as_that_setting_at_level_1():
    buffer = io.BytesIO()
    save_png(_figure(), buffer, 120)
    ours = buffer.getvalue()
    unhinted, hinted = _saved(**{"text.hinting": "no_hinting"}), _saved(**{"text.hinting": "default"})
    assert np.array_equal(_pixels(ours), _pixels(unhinted))  # the same pixels: only the rendering setting applies
    assert not np.array_equal(_pixels(ours), _pixels(hinted))  # ... and it does apply (the glyphs differ)
    assert PNG_OPTIONS == {"compress_level": 1} and RENDERING == {"text.hinting": "no_hinting"}
    # zlib's fastest level: the image data's zlib header says FLEVEL 0 (RFC 1950: 0x78 0x01), the default's 2 (0x9c)
    assert _zlib_header(ours) == b"\x78\x01" and _zlib_header(unhinted) == b"\x78\x9c"


def test_the_callers_rcparams_are_left_as_they_were_also_when_writing_fails(tmp_path):
    with matplotlib.rc_context({"text.hinting": "native"}):
        save_png(_figure(), tmp_path / "a.png", 100, bbox_inches="tight")
        assert matplotlib.rcParams["text.hinting"] == "native"
        with pytest.raises(OSError):
            save_png(_figure(), tmp_path / "missing" / "b.png", 100)
        assert matplotlib.rcParams["text.hinting"] == "native"
    assert Image.open(tmp_path / "a.png").format == "PNG"
