"""``heliostep.results.output.folder``'s swap holds the stop signals back, also those the kernel
delivers to another thread of the process (the race behind a double Ctrl+C that left a folder's
manifest at ``swapping``: tests/run/test_owned_folder.py), and a stop leaving a held folder removes
the command's temporary files."""

from __future__ import annotations

import subprocess
import sys

import pytest

PROGRAM = r"""
import os, signal, threading, time
from heliostep.results.output.folder import _stop_signals_blocked

events = []

def handler(signum, frame):
    events.append(f"handler {signum} in {threading.current_thread().name}")
    raise KeyboardInterrupt

signal.signal(signal.SIGINT, handler)
signal.signal(signal.SIGHUP, signal.SIG_IGN)
# a thread that does not mask the signals (started before the block): the kernel gives it the
# process-directed SIGINT, since the main thread masks it
threading.Thread(target=time.sleep, args=(3.0,), daemon=True).start()
time.sleep(0.05)
try:
    with _stop_signals_blocked():
        os.kill(os.getpid(), signal.SIGINT)
        os.kill(os.getpid(), signal.SIGINT)  # twice: delivered once on leaving, as a pending signal is
        os.kill(os.getpid(), signal.SIGHUP)  # ignored: stays ignored
        time.sleep(0.2)  # the other thread has taken it; Python would run the handler here
        for _ in range(10**6):
            pass
        events.append("block ended")
except KeyboardInterrupt:
    events.append("raised after the block")
assert signal.getsignal(signal.SIGINT) is handler and signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
print(";".join(events))
"""


@pytest.mark.skipif(not hasattr(__import__("signal"), "pthread_sigmask"), reason="POSIX signal masks")
def test_a_signal_taken_by_another_thread_is_held_back_until_the_swap_ends():
    result = subprocess.run([sys.executable, "-c", PROGRAM], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr[-3000:]
    assert result.stdout.strip() == "block ended;handler 2 in MainThread;raised after the block"


@pytest.mark.parametrize("stop", [KeyboardInterrupt, SystemExit])
def test_a_stop_leaving_a_held_folder_removes_its_temporaries_an_error_keeps_them(stop, tmp_path):
    """A stop (a BaseException that is not an Exception: a second Ctrl+C's ForcedStop is one) can
    come between a staging folder's making and the ``try`` that removes it: leaving the lock's
    block so removes every ``.heliostep-tmp-*`` entry. An error keeps them (a stream that nowhere
    else could take holds computed rows); the user's files stay either way."""
    from heliostep.cli.signals import ForcedStop
    from heliostep.results.output.folder import LOCK_NAME, hold_folder, staging_folder

    def made_in_the_block(folder, exc):
        with pytest.raises(type(exc)), hold_folder(folder):
            (staging_folder(folder) / "trace.parquet").write_bytes(b"half")
            (folder / ".heliostep-tmp-123-trace.parquet").write_bytes(b"rows")
            (folder / "notes.txt").write_text("the user's")
            raise exc
        return sorted(p.name for p in folder.iterdir())

    for exc in (stop(), ForcedStop(2)):
        folder = tmp_path / type(exc).__name__
        folder.mkdir()
        assert made_in_the_block(folder, exc) == ["notes.txt"]
    (tmp_path / "error").mkdir()
    kept = made_in_the_block(tmp_path / "error", RuntimeError("a bug"))
    assert LOCK_NAME not in kept and "notes.txt" in kept
    assert ".heliostep-tmp-123-trace.parquet" in kept and any(n.startswith(".heliostep-tmp-staging-") for n in kept)
