"""A page of heliostep's HTML rendered by headless Chromium (Debian's ``chromium``), driven by its command line
only: a screenshot, a printed PDF, and a measurement read back out of the rendered page (a copy of the page with
a script appended that, once the page has loaded, writes its findings as JSON into the page, which
``--dump-dom`` prints)."""

from __future__ import annotations

import html
import json
import re
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Any

#: An A4 page in CSS pixels (96 per inch): 210 x 297 mm.
A4_WIDTH, A4_HEIGHT = 794, 1123
#: Long enough for a page of a few MB of embedded PNGs on a loaded machine [s].
TIMEOUT = 120.0
#: Headless, and nothing started that would reach the network (a closed network refuses it noisily).
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
)

#: Once the page has loaded: every image (decoded or not, its natural width), the document's scroll and client
#: widths, and every element whose box ends right of the client width (its tag, class, right edge [CSS px] and
#: its section's heading).
PROBE = """<script>
window.addEventListener("load", () => {
  const root = document.documentElement, width = root.clientWidth;
  const images = Array.from(document.images, (img) => ({
    alt: img.alt, complete: img.complete, naturalWidth: img.naturalWidth, width: img.getBoundingClientRect().width,
  }));
  const wide = [];
  for (const element of document.body.querySelectorAll("*")) {
    const right = element.getBoundingClientRect().right;
    if (right > width + 0.5) {
      const heading = element.closest("section")?.querySelector("h1, h2")?.textContent ?? "";
      wide.push({tag: element.tagName, class: element.className, right: right, section: heading});
    }
  }
  const result = {clientWidth: width, scrollWidth: root.scrollWidth, images: images, wider: wide};
  const probe = document.createElement("pre");
  probe.id = "probe";
  probe.textContent = JSON.stringify(result);
  document.body.appendChild(probe);
});
</script>"""
_PROBE_OUT = re.compile(r'<pre id="probe">(.*?)</pre>', re.S)


def chromium() -> str | None:
    """The path of the ``chromium`` command, None where there is none."""
    return shutil.which("chromium")


def _run(page: Path, *options: str) -> str:
    """``chromium`` on ``page`` with ``options`` after the fixed flags and a profile of its own; its stdout."""
    command = chromium()
    if command is None:
        raise FileNotFoundError("chromium")
    with tempfile.TemporaryDirectory(prefix="heliostep-chromium-") as profile:
        argv = [command, *FLAGS, f"--user-data-dir={profile}", *options, page.resolve().as_uri()]
        done = subprocess.run(argv, capture_output=True, text=True, timeout=TIMEOUT, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"chromium exited {done.returncode}: {done.stderr[-2000:]}")
    return done.stdout


def measure(page: Path, width: int = A4_WIDTH, height: int = A4_HEIGHT) -> dict[str, Any]:
    """``page`` laid out in a window ``width`` x ``height`` [CSS px] and measured once loaded (see :data:`PROBE`):
    ``clientWidth``, ``scrollWidth``, ``images`` and ``wider`` (the elements reaching past the client width)."""
    with tempfile.TemporaryDirectory(prefix="heliostep-probe-") as folder:
        copy = Path(folder) / page.name
        text = page.read_text("utf-8")
        end = text.rfind("</body>")
        copy.write_text(text[:end] + PROBE + text[end:] if end >= 0 else text + PROBE, "utf-8")
        dom = _run(copy, f"--window-size={width},{height}", "--virtual-time-budget=5000", "--dump-dom")
    found = _PROBE_OUT.search(dom)
    if found is None:
        raise RuntimeError(f"no probe result in the page chromium dumped ({len(dom)} characters)")
    return json.loads(html.unescape(found.group(1)))


def screenshot(page: Path, png: Path, width: int = A4_WIDTH, height: int = A4_HEIGHT) -> Path:
    """``page`` as a PNG of its first ``width`` x ``height`` [CSS px], written to ``png``."""
    _run(page, f"--window-size={width},{height}", f"--screenshot={png.resolve()}")
    return png


def print_pdf(page: Path, pdf: Path) -> Path:
    """``page`` printed to ``pdf`` (the browser's default paper, without header and footer)."""
    _run(page, "--no-pdf-header-footer", f"--print-to-pdf={pdf.resolve()}")
    return pdf


def pdf_pages(pdf: bytes) -> int:
    """The number of page objects in a PDF as Chromium writes it (uncompressed object dictionaries)."""
    return len(re.findall(rb"/Type\s*/Page(?![a-zA-Z])", pdf))
