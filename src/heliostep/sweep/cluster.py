"""Running cases on dask.distributed: the local or given cluster, shipping FMUs, skipping done cases."""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import logging
import os
import socket
import time as clock
import uuid
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path

import pandas as pd

from heliostep.errors import InputError
from heliostep.fmu.build import ensure_fmu
from heliostep.progress import progress_bar
from heliostep.sweep import local_worker
from heliostep.sweep.certificate import CERTIFICATE_CASES
from heliostep.sweep.composed import run_with_families
from heliostep.sweep.spec import (
    SweepCase,
    SweepSpec,
    expand_cases,
    load_sweep,
    sweep_metadata,
)
from heliostep.sweep.store import (
    _consolidate,
    _normalize,
    _parts_dir,
    _write_atomically,
    _write_part,
    check_results_owner,
    default_results_path,
)
from heliostep.sweep.worker import (
    FmuPayload,
    _fmu_key,
    _fmu_payload,
    _lost_case_row,
    run_case,
)

#: Seconds between merges of the part files into the results table while a sweep runs.
CONSOLIDATE_EVERY = 30.0


@dataclasses.dataclass
class SweepOutcome:
    """What :func:`run_sweep` / :func:`execute_cases` did.

    Attributes
    ----------
    table : pandas.DataFrame
        The results table (one row per case of the sweep), as written.
    results_path : Path
    executed : int
        Cases run by this call.
    skipped : int
        Cases skipped because the table already held them.
    failed : int
        Cases of the table whose status is "failed".
    """

    table: pd.DataFrame
    results_path: Path
    executed: int
    skipped: int
    failed: int


def _worker_count() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def _probe_scheduler(address: str, timeout: float) -> None:
    """Fail at once (InputError) when a tcp:// scheduler address refuses connections."""
    from distributed.comm import parse_address
    from distributed.comm.addressing import parse_host_port
    from distributed.comm.registry import backends

    try:
        scheme, location = parse_address(address, strict=True)
        if scheme not in backends:
            raise ValueError(f"unknown scheme {scheme!r}; known: {', '.join(sorted(backends))}")
        host, port = parse_host_port(location) if scheme == "tcp" else (None, None)
    except ValueError as exc:
        raise InputError(f"scheduler {address!r}: expected an address such as tcp://HOST:8786 ({exc})") from None
    if scheme != "tcp":
        return
    deadline = clock.monotonic() + timeout
    try:
        with socket.create_connection((host, port), timeout=timeout) as connection:
            greeting = _first_message(connection, deadline)
    except OSError as exc:
        raise InputError(
            f"cannot reach the Dask scheduler at {address} ({exc.strerror or exc}); start one "
            f"with 'dask scheduler' or leave out --scheduler to run on a local cluster"
        ) from None
    if DASK_HANDSHAKE_KEY not in greeting:
        heard = "nothing" if not greeting else f"{greeting[:24]!r}"
        raise InputError(
            f"{address} answers but is not a Dask scheduler: no Dask handshake within {timeout:g} s "
            f"(--connect-timeout; it sent {heard}); give the scheduler's address, or leave out --scheduler"
        )


#: A Dask scheduler greets every new TCP connection with its handshake, a msgpack map whose keys
#: include this (distributed's TCP comm: ``Comm.handshake_info``, sent by both ends on connect).
DASK_HANDSHAKE_KEY = b"compression"


def _first_message(connection: socket.socket, deadline: float) -> bytes:
    """The first bytes a server sends on a new connection (up to 4 KiB), read until ``deadline``
    (:func:`time.monotonic`) or until the handshake key is in them; b"" if it sends nothing."""
    received = b""
    while len(received) < 4096 and DASK_HANDSHAKE_KEY not in received:
        left = deadline - clock.monotonic()
        if left <= 0:
            break
        connection.settimeout(left)
        try:
            chunk = connection.recv(4096 - len(received))
        except TimeoutError:
            break
        if not chunk:  # closed
            break
        received += chunk
    return received


@contextlib.contextmanager
def _dask_client(
    client=None, scheduler: str | None = None, n_workers: int | None = None, connect_timeout: float = 5.0
) -> Iterator:
    """A Dask client: the one given, one connected to ``scheduler``, or one on a new local cluster."""
    if client is not None:
        yield client
        return
    from distributed import Client, LocalCluster

    if scheduler:
        _probe_scheduler(scheduler, connect_timeout)
        try:
            connected = Client(scheduler, timeout=connect_timeout)
        except ValueError as exc:
            raise InputError(f"scheduler {scheduler!r}: not a usable Dask address ({exc})") from None
        except Exception as exc:  # noqa: BLE001 - timeouts, refusals, a non-Dask server answering
            raise InputError(
                f"cannot connect to a Dask scheduler at {scheduler} within {connect_timeout:g} s "
                f"({type(exc).__name__}: {str(exc)[:200]}); start one with 'dask scheduler' or "
                f"leave out --scheduler to run on a local cluster"
            ) from None
        with connected:
            yield connected
        return
    workers = n_workers or _worker_count()
    if workers < 1:
        raise InputError(f"n_workers must be >= 1, got {workers}")
    with (
        local_worker.held_while_starting() as release,  # its processes born with Ctrl+C held
        LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=":0",
            silence_logs=logging.ERROR,
            preload=[local_worker.PRELOAD],  # its workers leave the terminal's Ctrl+C to this process
        ) as cluster,
        Client(cluster) as local,
    ):
        try:
            release()  # a Ctrl+C that came while the cluster started is taken here: the cluster closes quietly
            yield local
        finally:
            _close_quietly(local, cluster)


def _close_quietly(client, cluster) -> None:
    """Close heliostep's own local cluster with distributed's messages silenced, in its workers and here.

    While a cluster closes, its processes can report the closing itself: a worker whose heartbeat finds
    the scheduler gone logs the failure with its traceback (``distributed.worker``, at ERROR), e.g. after
    a Ctrl+C that stopped a band mid-sample. Those are the shutdown's, not the user's; a failed case is
    reported by heliostep. The workers are told first (:func:`.local_worker.silence_distributed_logs`, errors
    ignored: a worker that is gone says nothing), then the client and the cluster are closed with this
    process's own handlers silenced the same way (the ``with`` around them then finds them closed).
    """
    from distributed.utils import silence_logging_cmgr

    try:
        client.run(local_worker.silence_distributed_logs, on_error="ignore")
    except Exception:  # noqa: BLE001 - a cluster already broken: closing it is all that is left
        pass
    with silence_logging_cmgr(logging.CRITICAL):
        client.close()
        cluster.close()


def _progress_bar(total: int, enabled: bool):
    return progress_bar(total, "cases", "case", enabled)


def _ship_fmus(cases: Sequence[SweepCase]) -> tuple[list[SweepCase], dict[str, FmuPayload]]:
    """Build (or find) every FMU the cases use, once, and read their bytes (a bare name: a model in
    ``models/`` beside the base scenario or the models folder, or an FMU in ``fmus/`` beside the base
    scenario or in the current folder, as ``run`` finds it)."""
    paths: dict[str, Path] = {}
    for case in cases:
        for instance, reference in case.scenario["fmus"].items():
            if reference is not None and reference not in paths:  # None: a default instance dropped
                try:  # where `run` looks too
                    paths[reference] = Path(ensure_fmu(reference, Path(case.folder)))
                except InputError as exc:
                    raise InputError(f"{case.source}: fmus.{instance}: {exc}") from None
    payloads, sha_of = {}, {}
    for reference, path in paths.items():
        data = path.read_bytes()
        sha = hashlib.sha256(data).hexdigest()
        payloads[sha] = FmuPayload(name=path.name, sha256=sha, data=data)
        sha_of[reference] = sha
    shipped = [
        dataclasses.replace(
            case,
            fmu_sha256={
                instance: sha_of[reference]
                for instance, reference in case.scenario["fmus"].items()
                if reference is not None
            },
        )
        for case in cases
    ]
    return shipped, payloads


def execute_cases(
    cases: Sequence[SweepCase],
    results_path: str | Path,
    *,
    client=None,
    scheduler: str | None = None,
    n_workers: int | None = None,
    connect_timeout: float = 5.0,
    retry_failed: bool = False,
    progress: bool = False,
    on_result: Callable[[dict], None] | None = None,
    metadata: Mapping | None = None,
    replace: bool = False,
    exact: bool = False,
    certify: int = CERTIFICATE_CASES,
    seed: int = 0,
) -> SweepOutcome:
    """Run the cases not yet in the results table on Dask, writing each row as it finishes.

    Parameters
    ----------
    cases : sequence of SweepCase
        From :func:`expand_cases` (validated).
    results_path : str or Path
        The Parquet table (its part files: ``<results_path>.parts/``).
    client, scheduler, n_workers, connect_timeout
        Use ``client`` (and its cluster) as it is; else connect to ``scheduler`` (``tcp://HOST:PORT``, trying for
        ``connect_timeout`` [s], default 5); else start a local cluster of ``n_workers`` (default: the cores).
    retry_failed, replace : bool, default False
        Run again the cases whose row says "failed" (else skipped); run even when the table holds another
        sweep's rows, dropping them (else refused).
    progress, on_result
        A progress bar when stderr is a terminal and ``CI`` is not set; a callable given each finished row.
    metadata : Mapping, optional
        Stored in the table's Parquet metadata (``heliostep.sweep``): the sweep's identity.
    exact, certify, seed
        Every case in full (``exact``), else each drive's cases composed from its step family, certified by
        ``certify`` cases drawn by ``seed`` and run in full (:mod:`heliostep.sweep.composed`).

    Returns
    -------
    SweepOutcome

    Raises
    ------
    InputError
        Before any case runs: a table of another sweep's rows, an FMU not found or built, no scheduler.
    """
    if certify < 1:
        raise InputError(f"certify: expected at least 1 case, got {certify}")
    results_path, metadata = Path(results_path), dict(metadata or {})
    check_results_owner(results_path, metadata, replace)
    cases, payloads = _ship_fmus(cases)
    if client is None and scheduler:
        _probe_scheduler(scheduler, connect_timeout)
    table, to_run = _table_and_cases_to_run(cases, results_path, metadata, retry_failed)
    dask = _DaskSettings(client, scheduler, n_workers, connect_timeout, progress, on_result, exact, certify, seed)
    table, executed = _run_and_consolidate(to_run, cases, payloads, results_path, metadata, table, dask)
    failed, skipped = int((table["status"] == "failed").sum()), len(cases) - len(to_run)
    return SweepOutcome(table=table, results_path=results_path, executed=executed, skipped=skipped, failed=failed)


@dataclasses.dataclass(frozen=True)
class _DaskSettings:
    """How a sweep reaches Dask and reports its rows (the options of :func:`execute_cases`)."""

    client: object | None
    scheduler: str | None
    n_workers: int | None
    connect_timeout: float
    progress: bool
    on_result: Callable[[dict], None] | None
    exact: bool = False
    certify: int = CERTIFICATE_CASES
    seed: int = 0


def _run_and_consolidate(
    to_run: Sequence[SweepCase],
    cases: Sequence[SweepCase],
    payloads: Mapping[str, FmuPayload],
    results_path: Path,
    metadata: Mapping,
    table: pd.DataFrame,
    dask: _DaskSettings,
) -> tuple[pd.DataFrame, int]:
    """Run *to_run* on Dask; then (also when that fails) merge the part files into the table of *cases*.
    Returns the table and how many cases ran."""
    executed = 0
    run_id = uuid.uuid4().hex[:12]
    try:
        if to_run:
            executed = _run_on_dask(to_run, payloads, results_path, metadata, run_id, dask)
    finally:
        if results_path.exists() or _parts_dir(results_path).is_dir():
            table = _consolidate(results_path, metadata, cases=cases)
    return table, executed


def _table_and_cases_to_run(
    cases: Sequence[SweepCase], results_path: Path, metadata: Mapping, retry_failed: bool
) -> tuple[pd.DataFrame, list[SweepCase]]:
    """The results table so far (its part files merged in; an empty one written if there is none) and the
    cases it has no finished row of: none yet, one whose FMUs differ, or (with ``retry_failed``) a failed one."""
    if results_path.exists() or _parts_dir(results_path).is_dir():
        table = _consolidate(results_path, metadata)
    else:  # written empty now, so that the table names its sweep before any row is in it
        table = _normalize(pd.DataFrame())
        _write_atomically(table, results_path, metadata)
    done_statuses = {"ok"} if retry_failed else {"ok", "failed"}
    finished = {row.case_id: row for row in table.itertuples(index=False) if row.status in done_statuses}
    to_run = [
        case
        for case in cases
        if case.case_id not in finished or finished[case.case_id].fmu_sha256 != _fmu_key(case.fmu_sha256)
    ]
    return table, to_run


def _run_on_dask(
    cases: Sequence[SweepCase],
    payloads: Mapping[str, FmuPayload],
    results_path: Path,
    metadata: Mapping,
    run_id: str,
    dask: _DaskSettings,
) -> int:
    with _dask_client(dask.client, dask.scheduler, dask.n_workers, dask.connect_timeout) as dask_client:
        shipped = {
            sha: dask_client.submit(_fmu_payload, payload, key=f"heliostep-fmu-{sha[:16]}-{run_id}", pure=False)
            for sha, payload in payloads.items()
            if any(sha in case.fmu_sha256.values() for case in cases)
        }
        last_merge = clock.monotonic()
        with _progress_bar(len(cases), dask.progress) as bar:
            tally = {"done": 0, "failed": 0}

            def record(row: dict) -> None:
                nonlocal last_merge
                _write_part(row, results_path)
                tally["done"] += 1
                tally["failed"] += row["status"] == "failed"
                bar.set_postfix(**tally, remaining=len(cases) - tally["done"], refresh=False)
                bar.update(1)
                if dask.on_result is not None:
                    dask.on_result(row)
                if clock.monotonic() - last_merge > CONSOLIDATE_EVERY:
                    _consolidate(results_path, metadata)
                    last_merge = clock.monotonic()

            if dask.exact:
                done = _run_in_full(dask_client, cases, shipped, run_id, record)
            else:
                done = run_with_families(dask_client, cases, shipped, record, run_id, dask.certify, dask.seed)
        for future in shipped.values():
            future.release()
    return done


def _run_in_full(client, cases: Sequence[SweepCase], shipped: Mapping, run_id: str, record) -> int:
    """Every case co-simulated (``shipped``: SHA-256 -> the FMU payload's future); each row to ``record``."""
    from distributed import as_completed

    futures = {}
    for case in cases:
        needed = {sha: shipped[sha] for sha in set(case.fmu_sha256.values())}
        key = f"heliostep-case-{case.case_id}-{run_id}"
        futures[client.submit(run_case, case, needed, run_id, pure=False, key=key)] = case
    for future in as_completed(futures):
        case = futures.pop(future)
        try:
            row = future.result()
        except Exception as exc:  # noqa: BLE001 - e.g. KilledWorker: record, go on
            row = _lost_case_row(case, exc, run_id)
        future.release()
        record(row)
    return len(cases)


def run_sweep(
    sweep: SweepSpec | str | Path,
    results_path: str | Path | None = None,
    *,
    client=None,
    scheduler: str | None = None,
    n_workers: int | None = None,
    connect_timeout: float = 5.0,
    retry_failed: bool = False,
    progress: bool = False,
    on_result: Callable[[dict], None] | None = None,
    replace: bool = False,
    exact: bool = False,
    certify: int = CERTIFICATE_CASES,
    seed: int = 0,
) -> SweepOutcome:
    """Run a sweep: validate every case, then run the unfinished ones on Dask.

    Parameters
    ----------
    sweep : SweepSpec or str or Path
        A sweep, or the path of a sweep file.
    results_path : str or Path, optional
        Default :func:`default_results_path`.
    client, scheduler, n_workers, connect_timeout, retry_failed, progress, on_result, replace, exact, certify, seed
        See :func:`execute_cases`.

    Returns
    -------
    SweepOutcome

    Raises
    ------
    InputError
        Bad sweep or case scenario, unknown FMU, unreachable scheduler, a table holding another sweep's
        rows: before any case runs.
    """
    spec = sweep if isinstance(sweep, SweepSpec) else load_sweep(sweep)
    cases = expand_cases(spec)
    path = Path(results_path) if results_path is not None else default_results_path(spec)
    return execute_cases(
        cases,
        path,
        client=client,
        scheduler=scheduler,
        n_workers=n_workers,
        connect_timeout=connect_timeout,
        retry_failed=retry_failed,
        progress=progress,
        on_result=on_result,
        metadata=sweep_metadata(spec),
        replace=replace,
        exact=exact,
        certify=certify,
        seed=seed,
    )
