"""heliostep.run.supervision.allocator: a Dask worker's fixed heap thresholds undone.

With ``MALLOC_TRIM_THRESHOLD_`` set (Dask's nanny sets 65536 in every worker), glibc's mmap threshold
stays at 128 KiB, so each array of 1 MiB is a fresh mmap whose 256 pages of 4 KiB fault in again every
time it is filled. After :func:`restore_dynamic_heap` the heap keeps and reuses them: next to no faults.
Counted with getrusage's minor faults, in a fresh process, and in a real Dask worker on loopback.
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")

ALLOCATIONS = 200  # arrays of 1 MiB (131 072 float64), each filled once
PAGES = (1 << 20) // 4096  # the pages of one, faulted in when it is a fresh mmap


def fault_counts() -> tuple[int, int, bool]:
    """Minor page faults of filling :data:`ALLOCATIONS` fresh 1 MiB arrays, before and after
    restore_dynamic_heap, and what it returned (run where the test sends it: a child, a Dask worker)."""
    import resource

    import numpy as np

    from heliostep.run.supervision.allocator import restore_dynamic_heap

    def faults() -> int:
        before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        for _ in range(ALLOCATIONS):
            np.ones(PAGES * 512)  # 1 MiB, filled, freed
        return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before

    first = faults()
    restored = restore_dynamic_heap()
    faults()  # the heap grows to hold one array once
    return first, faults(), restored


def _in_child(environment: dict) -> tuple[int, int, bool]:
    code = "import sys; sys.path.insert(0, sys.argv[1]); import test_allocator as t; print(*t.fault_counts())"
    out = subprocess.run(
        [sys.executable, "-c", code, os.path.dirname(__file__)], env=environment, capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    first, after, restored = out.stdout.split()
    return int(first), int(after), restored == "True"


def test_with_the_trim_variable_set_every_array_faults_in_and_after_the_restore_next_to_none():
    first, after, restored = _in_child({**os.environ, "MALLOC_TRIM_THRESHOLD_": "65536"})
    assert restored
    assert first > 0.9 * ALLOCATIONS * PAGES  # each array its own mmap: 256 faults each
    assert after < 0.02 * ALLOCATIONS * PAGES  # reused from the heap


def test_without_the_variable_glibc_is_left_alone():
    environment = {key: value for key, value in os.environ.items() if key != "MALLOC_TRIM_THRESHOLD_"}
    first, after, restored = _in_child(environment)
    assert not restored
    assert first < 0.1 * ALLOCATIONS * PAGES  # glibc's dynamic threshold already rose past 1 MiB


def test_in_a_dask_worker_the_restore_takes_its_faults_away():
    from distributed import Client, LocalCluster

    with (
        LocalCluster(
            n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=":0",
            silence_logs=logging.ERROR,
        ) as cluster,
        Client(cluster) as client,
    ):  # fmt: skip
        client.run(sys.path.insert, 0, os.path.dirname(__file__))
        environ = next(iter(client.run(lambda: dict(os.environ)).values()))
        assert environ.get("MALLOC_TRIM_THRESHOLD_") == "65536"  # Dask's nanny sets it: the reason for all this
        first, after, restored = client.submit(fault_counts, pure=False).result()
    assert restored
    assert first > 0.9 * ALLOCATIONS * PAGES
    assert after < 0.02 * ALLOCATIONS * PAGES
