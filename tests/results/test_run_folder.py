"""``heliostep.results.run_folder``'s swap holds the stop signals back, also those the kernel
delivers to another thread of the process (the race behind a double Ctrl+C that left a folder's
manifest at ``swapping``: tests/run/test_owned_folder.py)."""

from __future__ import annotations

import subprocess
import sys

import pytest

PROGRAM = r"""
import os, signal, threading, time
from heliostep.results.run_folder import _stop_signals_blocked

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
