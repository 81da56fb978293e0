"""heliostep's own local cluster closes without distributed's shutdown messages on the terminal.

A worker whose heartbeat finds the scheduler already gone logs the failure with its traceback at ERROR
(``distributed.worker``); it was seen once after a Ctrl+C that stopped a band mid-sample
(``tests/sweep/test_band.py::test_ctrl_c_during_the_band_keeps_the_nominal_run`` asserts no traceback).
That race cannot be forced, so these tests make a worker log at ERROR while it closes, the same way
(a worker plugin's teardown, called by ``Worker.close``), on a real two-process local cluster in a
child process whose stderr is the terminal's.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

MESSAGE = "a worker's message while its cluster closes"

PROGRAM = textwrap.dedent(
    f"""
    import logging
    import sys

    from distributed import Client, LocalCluster
    from distributed.diagnostics.plugin import WorkerPlugin

    from heliostep.sweep.cluster import _dask_client


    class LogsWhileClosing(WorkerPlugin):
        def teardown(self, worker):
            try:
                raise ConnectionError("the scheduler is gone")
            except ConnectionError:
                logging.getLogger("distributed.worker").exception({MESSAGE!r})


    if sys.argv[1] == "heliostep":
        with _dask_client(n_workers=1) as client:
            client.register_plugin(LogsWhileClosing())
            assert client.submit(sum, [1, 2]).result() == 3
    else:  # the same cluster closed as distributed closes it
        with (
            LocalCluster(
                n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=":0",
                silence_logs=logging.ERROR,
            ) as cluster,
            Client(cluster) as client,
        ):
            client.register_plugin(LogsWhileClosing())
            assert client.submit(sum, [1, 2]).result() == 3
    print("closed")
    """
)


def _close(how: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", PROGRAM, how], capture_output=True, text=True, timeout=120)


def test_a_workers_error_while_heliosteps_cluster_closes_does_not_reach_the_terminal():
    closed = _close("heliostep")
    assert closed.returncode == 0, closed.stderr
    assert closed.stdout.strip() == "closed"
    assert MESSAGE not in closed.stderr, closed.stderr
    assert "Traceback" not in closed.stderr, closed.stderr


def test_the_same_error_reaches_the_terminal_when_distributed_closes_the_cluster_itself():
    """The control: without heliostep's quiet close the worker's message and traceback are printed,
    so the test above can fail."""
    closed = _close("distributed")
    assert closed.returncode == 0, closed.stderr
    assert MESSAGE in closed.stderr and "ConnectionError: the scheduler is gone" in closed.stderr, closed.stderr
