"""A real Dask cluster on loopback for the tests: worker processes, one thread each, no dashboard."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from distributed import Client, LocalCluster


@contextmanager
def loopback_client(n_workers: int = 2, **env: str) -> Iterator[Client]:
    """A client of a local cluster of ``n_workers`` processes on 127.0.0.1, their environment ``env`` added;
    the workers are up when it is yielded, and the cluster is closed after."""
    with (
        LocalCluster(
            n_workers=n_workers, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=":0", env=env
        ) as cluster,
        Client(cluster) as client,
    ):
        client.wait_for_workers(n_workers)
        yield client
