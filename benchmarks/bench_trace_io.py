"""Parquet encodings of a trace, side by side (prints figures; not a test).

    .venv/bin/python benchmarks/bench_trace_io.py [--repeat 3]

Simulates a case of ``scenarios/sweeps/year-field.yaml`` once (``jan21-central.yaml`` from
sunrise to sunset on a 1 s grid: the trace a sweep case streams; held in memory), then writes its first
131 072 rows as 8 row groups of 16 384 rows (the row group of a streamed trace) to memory with
several ParquetWriter settings, best of ``--repeat``, and reads each back: write time, read time,
size. The first line is the trace's setting (:data:`heliostep.results.trace.files.TRACE_ENCODING`,
zstd); the others are what it was chosen against, Parquet's default dictionary encoding first.
"""

from __future__ import annotations

import argparse
import io
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ROW_GROUP = 16384
GROUPS = 8
#: the overrides of scenarios/sweeps/year-field.yaml
YEAR_FIELD_CASE = ("window.start=sunrise", "window.end=sunset", "window.duration=null", "output.interval=1.0")


def main(argv: list[str] | None = None) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    from heliostep.results.trace.files import TRACE_ENCODING
    from heliostep.run import RunOptions, run_scenario

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    scenario = ROOT / "scenarios" / "jan21-central.yaml"
    trace = run_scenario(scenario, RunOptions(stream=False), overrides=YEAR_FIELD_CASE).trace
    table = pa.Table.from_pandas(trace.iloc[: ROW_GROUP * GROUPS], preserve_index=False)
    print(
        f"{table.num_rows} rows x {table.num_columns} float64 columns of a year-field case (21 January), "
        f"{GROUPS} row groups of {ROW_GROUP}; best of {args.repeat}"
    )
    settings = [
        ("trace (byte stream split + zstd)", {"compression": "zstd", **TRACE_ENCODING}),
        ("dictionary + zstd (Parquet default)", {"compression": "zstd"}),
        ("plain + zstd", {"compression": "zstd", "use_dictionary": False}),
        ("plain, uncompressed", {"compression": "none", "use_dictionary": False}),
        ("plain + lz4", {"compression": "lz4", "use_dictionary": False}),
    ]
    for name, options in settings:
        writes, reads = [], []
        for _ in range(args.repeat):
            buffer = io.BytesIO()
            started = time.perf_counter()
            with pq.ParquetWriter(buffer, table.schema, store_schema=False, **options) as writer:
                for k in range(GROUPS):
                    writer.write_table(table.slice(k * ROW_GROUP, ROW_GROUP))
            writes.append(time.perf_counter() - started)
            buffer.seek(0)
            started = time.perf_counter()
            back = pq.read_table(buffer)
            reads.append(time.perf_counter() - started)
            if not all(back.column(c).equals(table.column(c)) for c in table.column_names):
                raise SystemExit(f"{name}: the rows read back differ from those written")
        print(
            f"  {name:38s} write {min(writes) * 1e3:7.1f} ms   read {min(reads) * 1e3:6.1f} ms   "
            f"{len(buffer.getvalue()) / 1e6:6.2f} MB"
        )


if __name__ == "__main__":
    main()
