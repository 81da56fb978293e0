"""What a command says on standard error while it works: progress bars and one-line notes.

Standard output is data (a command's report, piped or parsed); progress goes to standard error only.
A bar is drawn only on a terminal and not in CI (:func:`bars_wanted`): a log or a pipe gets no
carriage-return noise, and a bar can then never write into a closed descriptor or a pipe whose reader
went away. A note (:func:`note`, e.g. an FMU built at first use) is written whatever standard error is,
and never raises: a standard error that fails loses the note, not the command.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["bars_wanted", "note", "over_bars", "progress_bar"]


def bars_wanted() -> bool:
    """True when standard error is a terminal and the environment is not CI (``$CI`` unset or empty)."""
    stream = sys.stderr
    try:
        return stream is not None and stream.isatty() and not os.environ.get("CI")
    except (OSError, ValueError):  # a closed stream
        return False


def progress_bar(total: float, desc: str, unit: str, enabled: bool = True, **options):
    """A tqdm bar on standard error over ``total`` ``unit``s, disabled unless ``enabled`` and
    :func:`bars_wanted`; ``options`` go to tqdm (e.g. ``delay`` [s] before it shows)."""
    from tqdm import tqdm

    quiet = not (enabled and bars_wanted())
    return tqdm(total=total, desc=desc, unit=unit, disable=quiet, file=sys.stderr, mininterval=0.5, **options)


@contextmanager
def over_bars() -> Iterator[None]:
    """Standard output written inside: the bars on the terminal cleared first and redrawn after (else the
    report would run on from a bar's line)."""
    if "tqdm" not in sys.modules:
        yield
        return
    from tqdm import tqdm

    with tqdm.external_write_mode(file=sys.stdout):
        yield


def note(line: str) -> None:
    """``line`` on standard error (over any bar, which is redrawn after it); nothing if it cannot be written."""
    stream = sys.stderr
    if stream is None:
        return
    try:
        if "tqdm" in sys.modules:  # a bar may be on the terminal: cleared, the line written, the bar redrawn
            from tqdm import tqdm

            tqdm.write(line, file=stream)
            stream.flush()
        else:
            print(line, file=stream, flush=True)
    except (OSError, ValueError):  # a reader gone, a full device, a closed stream: the note is lost
        pass
