"""Tests of heliostep.sweep.store: a finished case's part file, written straight in Arrow, reads back as the
same row the table's pandas normalisation makes of it (its dtypes, its order, its coercions)."""

from __future__ import annotations

import math

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from heliostep.sweep.store import _normalize, _write_part, read_results


def _rows() -> list[dict]:
    """Rows with every kind of value a column may get: a full composed case's, and one of a failed case with
    missing figures, a number given as text, text where a number is due and axis columns of several types."""
    composed = {
        "case_id": "a1",
        "case_index": 3,
        "role": "drive",
        "day_of_year": 21,
        "mirror_index": 12,
        "date": "2025-01-21",
        "motor": "StepperMotor",
        "current_A": 5.5,
        "peak_torque_Nm": 1.25,
        "missed_steps": 0,
        "steps_commanded": 2085,
        "status": "ok",
        "method": "composed",
        "fallback": None,
        "wall_time_s": 0.061,
        "deviation_peak_torque_Nm": 4.2e-4,
    }
    failed = {
        "case_id": "b2",
        "case_index": 4,
        "role": "drive",
        "day_of_year": 22,
        "mirror_index": None,
        "flag": True,
        "peak_torque_Nm": "1.5",
        "electrical_energy_J": "not a number",
        "missed_steps": None,
        "steps_commanded": math.nan,
        "status": "failed",
        "error": 7,
        "error_type": "SolverError",
    }
    return [composed, failed]


def test_a_part_reads_back_as_the_normalised_row(tmp_path):
    """Each row written as a part has the Arrow types of the normalised pandas row written through pandas, and
    reads back (read_results) as the same frame: every column, value and dtype."""
    for row in _rows():
        fast, slow = (
            tmp_path / f"fast-{row['case_id']}" / "results.parquet",
            tmp_path / f"slow-{row['case_id']}.parquet",
        )
        _write_part(row, fast)
        expected = pa.Table.from_pandas(_normalize(pd.DataFrame([row])), preserve_index=False)
        pq.write_table(expected, slow)
        part = pa.ipc.open_file(fast.with_name(fast.name + ".parts") / f"{row['case_id']}.arrow").read_all()
        assert part.schema.remove_metadata().equals(expected.schema.remove_metadata())  # the part's own types
        found, wanted = read_results(fast), _normalize(pq.read_table(slow).to_pandas())
        assert list(found.columns) == list(wanted.columns)
        pd.testing.assert_frame_equal(found, wanted, check_dtype=True)
    assert (
        math.isnan(found["electrical_energy_J"].iloc[0]) and found["peak_torque_Nm"].iloc[0] == 1.5
    )  # (the failed row)
    assert found["error"].iloc[0] == "7" and pd.isna(found["missed_steps"].iloc[0])


def test_parts_of_every_kind_merge_into_the_rows_pandas_makes_of_them(tmp_path):
    """Parts written as a sweep writes them, a part an earlier heliostep wrote (Parquet through pandas) and one
    cut short read back as the rows the pandas route makes of the readable ones: an axis of numbers stays
    numbers (ints with floats become floats), one of numbers and text becomes text, the cut part is left out."""
    rows = [
        {**row, "case_id": f"{row['case_id']}{k}", "finished_at": f"2026-01-0{k + 1}"} for k, row in enumerate(_rows())
    ]
    rows[0]["tilt"] = 1
    rows += [{**rows[0], "case_id": "c3", "case_index": 9, "tilt": 2.5, "flag": "yes"}]
    results = tmp_path / "results.parquet"
    for row in rows[:2]:
        _write_part(row, results)
    legacy = pa.Table.from_pandas(_normalize(pd.DataFrame([rows[2]])), preserve_index=False)
    parts = tmp_path / "results.parquet.parts"
    pq.write_table(legacy, parts / "c3.parquet")
    (parts / "cut.arrow").write_bytes((parts / "a10.arrow").read_bytes()[:200])
    found = read_results(results)
    frames = [_normalize(pd.DataFrame([row])) for row in rows]
    wanted = _normalize(pd.concat(frames, ignore_index=True)).sort_values("case_index", kind="stable")
    pd.testing.assert_frame_equal(found, wanted.reset_index(drop=True), check_dtype=True)
    assert found["tilt"].tolist()[::2] == [1.0, 2.5] and found["flag"].tolist()[1:] == ["True", "yes"]
