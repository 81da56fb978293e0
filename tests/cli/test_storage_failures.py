"""A full disk or a file-size limit while the trace is written is a run failure (exit 1) whose
rescue holds every computed row (issue 22, item 3).

The limit is real: ``RLIMIT_FSIZE`` set in the child before it runs ``heliostep run`` (SIGXFSZ
ignored there, so a write past the limit fails with EFBIG as on a full disk instead of killing
the process). The rows rescued are compared with those of the same run written without a limit.
"""

from __future__ import annotations

import json
import os
import re
import resource
import signal
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from heliostep.results.trace.files import read_trace
from heliostep_process import HELIOSTEP


def _run(args: list[str], tmp: Path, limit: int | None = None) -> subprocess.CompletedProcess:
    def limited() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    tmp.mkdir(exist_ok=True)
    return subprocess.run(
        [*HELIOSTEP, "run", *args],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "TMPDIR": str(tmp)},
        preexec_fn=limited if limit is not None else None,
    )


def _rescued(stderr: str) -> Path:
    found = re.search(r"the results were written to (\S+) instead", stderr)
    assert found, stderr
    return Path(found.group(1))


def _rescued_trace(folder: Path, scenario: str) -> pd.DataFrame:
    parts = sorted(folder.glob("trace-part-*.parquet")) or [folder / "trace.parquet"]
    frames = []
    for part in parts:
        frame, meta = read_trace(part)
        assert meta["scenario"] == scenario
        frames.append(frame)
    return pd.concat(frames, ignore_index=True)


def _record(folder: Path, name: str) -> dict:
    pieces = sorted(folder.glob(f"{name}.part-*")) or [folder / name]
    return json.loads(b"".join(p.read_bytes() for p in pieces))


@pytest.mark.parametrize(
    "scenario, extra, limit",
    [
        ("jan21-central", ["--set", "window.duration=300"], 200_000),  # held in memory, written at the end
        ("jan21-day", [], 300_000),  # over an hour: streamed while simulating
    ],
)
def test_a_file_size_limit_fails_the_run_and_the_rescue_holds_every_row(scenario, extra, limit, tmp_path, fmu_paths):
    free = _run([scenario, "--out", str(tmp_path / "free"), "--no-plots", *extra], tmp_path / "tmp-free")
    assert free.returncode == 0, free.stderr
    expected, _ = read_trace(tmp_path / "free" / "trace.parquet")
    assert (tmp_path / "free" / "trace.parquet").stat().st_size > limit  # the limit bites

    out = tmp_path / "out"
    limited = _run([scenario, "--out", str(out), "--no-plots", *extra], tmp_path / "tmp", limit)
    assert limited.returncode == 1, limited.stderr  # a run failure, not bad input
    assert "Traceback" not in limited.stderr and "File too large" in limited.stderr
    assert f"could not write the results to {out}" in limited.stderr
    rescue = _rescued(limited.stderr)
    assert rescue.parent == tmp_path / "tmp"
    assert all(p.stat().st_size <= limit for p in rescue.iterdir())
    trace = _rescued_trace(rescue, scenario)
    # every computed row, bit for bit those of the run written without a limit
    pd.testing.assert_frame_equal(trace, expected[list(trace.columns)], check_exact=True)
    assert list(trace.columns) == list(expected.columns)
    summary = _record(rescue, "summary.json")
    metadata = _record(rescue, "metadata.json")
    assert summary["rows"] == len(expected) and metadata["scenario"]["name"] == scenario
    # held: the simulation had ended when the write failed; streamed: it failed with the write
    # (the last group's write came after the last row), and says why
    assert summary["complete"] is (scenario == "jan21-central")
    assert summary["complete"] or "could not be written" in summary["error"]
    # nothing half-written in --out: no temporary file, no lock, nothing claiming completeness
    assert [p.name for p in out.iterdir() if not p.name.startswith(".heliostep-manifest")] == []


CHILD = """
import resource, signal, sys
from pathlib import Path
from heliostep.run import RunFailed, RunOptions, run_scenario
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
limit = int(sys.argv[1])
resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
try:
    run_scenario("jan21-day", RunOptions(stream=True, row_group_rows=500, trace_dir=sys.argv[2]))
    sys.exit("the run did not fail")
except RunFailed as failed:
    result = failed.result
    print(result.error)
    print(len(result.unwritten_trace), result.trace_rows)
    result.write_rescue(Path(sys.argv[3]))
"""


def test_a_stream_cut_short_keeps_its_row_groups_and_the_rows_after_them(tmp_path, fmu_paths):
    """Row groups of 500 rows: the first ones fit under the limit, then a write fails and the run
    fails there; the file keeps those groups, the rows after them are held in memory, and the
    rescue has every row computed, in order: those of the unlimited run up to the failure."""
    free = _run(["jan21-day", "--out", str(tmp_path / "free"), "--no-plots"], tmp_path / "tmp-free")
    assert free.returncode == 0, free.stderr
    expected, _ = read_trace(tmp_path / "free" / "trace.parquet")
    (tmp_path / "stream").mkdir()
    (tmp_path / "rescue").mkdir()
    child = subprocess.run(
        [sys.executable, "-c", CHILD, "150000", str(tmp_path / "stream"), str(tmp_path / "rescue")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert child.returncode == 0, child.stderr
    error, counts = child.stdout.strip().splitlines()[-2:]
    unwritten, total = map(int, counts.split())
    kept = int(re.search(r"the file keeps the (\d+) rows", error).group(1))
    assert kept > 0 and kept % 500 == 0 and unwritten > 0  # some row groups written, then the failure
    assert kept + unwritten == total < len(expected)  # the run fails there: every row computed until then
    trace = _rescued_trace(tmp_path / "rescue", "jan21-day")
    pd.testing.assert_frame_equal(trace, expected[list(trace.columns)].iloc[:total], check_exact=True)
    assert _record(tmp_path / "rescue", "summary.json")["rows"] == total
