"""heliostep.cli.signals in-process: a stop signal that lands inside a callback Python cannot
raise out of (a weakref callback, as matplotlib's transforms have) is not lost."""

from __future__ import annotations

import signal
import time
import weakref

import pytest

from heliostep.cli.signals import ForcedStop, stop_requests


class _Node:
    pass


def _second_signal_inside_a_weakref_callback() -> list[str]:
    """The first SIGINT in plain code, the second one while a weakref callback runs; returns
    what the code after the callback got to do."""
    reached = []
    signal.raise_signal(signal.SIGINT)  # the first: only recorded
    node = _Node()

    def callback(_):
        signal.raise_signal(signal.SIGINT)  # the second: its handler runs in this callback's bytecode
        total = 0
        for k in range(1000):
            total += k
        reached.append("callback ended")

    ref = weakref.ref(node, callback)
    del node  # the callback runs here; an exception raised in it cannot propagate
    assert ref() is None and reached == []  # the handler's exception ended the callback
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline:  # plain code: where the stop must arrive
        pass
    reached.append("went on after the callback")
    return reached


def test_a_second_signal_inside_a_weakref_callback_still_forces_the_stop(capsys):
    started = time.monotonic()
    with pytest.raises(ForcedStop) as stopped:
        with stop_requests() as request:
            _second_signal_inside_a_weakref_callback()
    assert time.monotonic() - started < 5.0  # raised after the callback, not at the end of the wait
    assert stopped.value.signum == signal.SIGINT and request.count == 2  # raised again, not counted again
    assert "Exception ignored" not in capsys.readouterr().err


def test_the_hook_is_restored_and_other_unraisable_exceptions_reach_it():
    import sys

    before = sys.unraisablehook
    seen = []
    sys.unraisablehook = seen.append
    try:
        with stop_requests():
            node = _Node()
            weakref.finalize(node, lambda: 1 / 0)
            del node
        assert len(seen) == 1 and isinstance(seen[0].exc_value, ZeroDivisionError)
        assert sys.unraisablehook == seen.append
    finally:
        sys.unraisablehook = before


def test_a_second_signal_wrapped_by_an_import_is_still_a_forced_stop(capsys):
    """An extension module's initialization turns an exception raised in it (the second signal's ForcedStop,
    when the signal lands during an import) into ``ImportError`` caused by it: still one line and 128 + n."""
    import argparse

    from heliostep.cli import _run

    def command(args):
        try:
            raise ForcedStop(signal.SIGINT)
        except ForcedStop as forced:
            raise ImportError("initialization failed") from forced

    assert _run("heliostep run", argparse.Namespace(func=command)) == 128 + signal.SIGINT
    err = capsys.readouterr().err
    assert "stopped by SIGINT a second time" in err and "Traceback" not in err

    def failing(args):
        raise ImportError("a real import failure")

    with pytest.raises(ImportError, match="a real import failure"):  # any other error is not taken for a stop
        _run("heliostep run", argparse.Namespace(func=failing))
