"""Modelica tools' result files read as traces: the Dymola / OpenModelica ``.mat`` layout (written here
with scipy in MAT v4, as Dymola writes it) and OpenModelica's CSV."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.io import savemat

from heliostep.cli import main
from heliostep.errors import InputError
from heliostep.results.trace.files import read_trace, write_trace
from heliostep.results.trace.modelica import unit_of_description

TIME = np.array([0.0, 0.25, 0.5, 0.5, 0.75, 1.0])  # an event at 0.5 s: two rows
TAU = np.array([0.0, 0.1, 0.2, 1.7, 1.3, 1.25])
THETA = np.sin(TIME) * 1e-3 + np.pi / 7


def _chars(strings: list[str], transposed: bool) -> np.ndarray:
    """A char matrix, one string per row padded with blanks (or, transposed, per column)."""
    width = max(len(s) for s in strings)
    matrix = np.array([list(s.ljust(width)) for s in strings])
    # scipy's MAT v4 writer needs C order (it writes a transposed view's memory as it lies)
    return np.ascontiguousarray(matrix.T) if transposed else matrix


def write_dymola_mat(path, transposed: bool = True, aclass: str = "Atrajectory", column_of_theta: int = 3):
    """A result file in the Dymola layout: time, a torque, its negated alias, a rotor angle, a
    parameter (data_1) and a negated alias of the parameter."""
    names = ["Time", "motor.tau", "mechanics.theta", "motor.k", "load.tau", "minus_k"]
    descriptions = ["Time in [s]", "Motor torque [N.m]", "Rotor angle [rad|deg]", "Torque constant [N.m/A]", "", "-k"]
    # dataInfo rows (matrix, signed column, interpolation, extrapolation)
    info = np.array(
        [[0, 1, 0, -1], [2, 2, 0, -1], [2, column_of_theta, 0, -1], [1, 2, 0, 0], [2, -2, 0, -1], [1, -2, 0, 0]],
        dtype=np.int32,
    )
    data_1 = np.array([[TIME[0], 0.125], [TIME[-1], 0.125]])  # rows: start and end; columns: time, k
    data_2 = np.column_stack([TIME, TAU, THETA])  # one row per time point
    contents = {
        "Aclass": _chars([aclass, "1.1", "", "binTrans" if transposed else "binNormal"], False),
        "name": _chars(names, transposed),
        "description": _chars(descriptions, transposed),
        "dataInfo": info.T.copy() if transposed else info,
        "data_1": data_1.T.copy() if transposed else data_1,
        "data_2": data_2.T.copy() if transposed else data_2,
    }
    savemat(str(path), contents, format="4")
    return path


@pytest.mark.parametrize("transposed", [True, False], ids=["binTrans", "binNormal"])
def test_a_dymola_layout_mat_file_reads_back_exactly(tmp_path, transposed):
    frame, meta = read_trace(write_dymola_mat(tmp_path / "dsres.mat", transposed))
    assert list(frame.columns) == ["time", "motor.tau", "mechanics.theta", "motor.k", "load.tau", "minus_k"]
    assert np.array_equal(frame["time"], TIME)
    assert np.array_equal(frame["motor.tau"], TAU)
    assert np.array_equal(frame["mechanics.theta"], THETA)
    assert np.array_equal(frame["load.tau"], -TAU)  # a negative column index: the negated alias
    assert np.array_equal(frame["motor.k"], np.full(TIME.size, 0.125))  # a parameter, held
    assert np.array_equal(frame["minus_k"], np.full(TIME.size, -0.125))
    assert meta["unit.motor.tau"] == "N.m" and meta["unit.mechanics.theta"] == "rad"  # unit, not displayUnit
    assert meta["unit.motor.k"] == "N.m/A" and "unit.load.tau" not in meta and meta["unit.time"] == "s"


def test_units_are_the_bracket_at_the_end_of_a_description():
    assert unit_of_description("Rotor angle [rad|deg]") == "rad"
    assert unit_of_description("Torque [N.m]") == "N.m"
    assert unit_of_description("Flag [1] set") is None
    assert unit_of_description("no unit") is None


def test_a_mat_file_that_is_not_a_modelica_result_is_bad_input(tmp_path):
    with pytest.raises(InputError, match="expected 'Atrajectory'"):
        read_trace(write_dymola_mat(tmp_path / "a.mat", aclass="Something"))
    with pytest.raises(InputError, match="dataInfo column 9 is outside data_2"):
        read_trace(write_dymola_mat(tmp_path / "b.mat", column_of_theta=9))
    (tmp_path / "c.mat").write_bytes(b"not a mat file at all")
    with pytest.raises(InputError, match="c.mat"):
        read_trace(tmp_path / "c.mat")


def test_compare_reads_a_mat_file_with_its_units(tmp_path, capsys):
    mat = write_dymola_mat(tmp_path / "dsres.mat")
    reference = tmp_path / "reference.parquet"
    moved = pd.DataFrame({"time": TIME, "motor.tau": TAU + np.where(TIME > 0.6, 0.5, 0.0)})
    write_trace(moved, reference)
    status = main(["compare", str(mat), str(reference), "--time-tol", "0"])
    out = capsys.readouterr().out
    assert status == 1
    row = next(line for line in out.splitlines() if line.startswith("motor.tau "))
    assert row.split()[1] == "FAIL" and row.split()[-1] == "N.m"  # the unit from the .mat's description


def test_openmodelica_csv_with_a_quoted_header_and_trailing_separators(tmp_path):
    # OpenModelica's CSV result: every name quoted, every line ending with the separator
    text = '"time","motor.tau","der(mechanics.theta)",\n' + "".join(
        f"{float(t)!r},{float(tau)!r},{float(-tau)!r},\n" for t, tau in zip(TIME, TAU)
    )
    (tmp_path / "model_res.csv").write_text(text)
    frame, meta = read_trace(tmp_path / "model_res.csv")
    assert list(frame.columns) == ["time", "motor.tau", "der(mechanics.theta)"] and meta == {}
    assert np.array_equal(frame["time"], TIME) and np.array_equal(frame["motor.tau"], TAU)
    assert np.array_equal(frame["der(mechanics.theta)"], -TAU)
    (tmp_path / "bad.csv").write_text('"time","a",\n0,1,2\n')
    with pytest.raises(InputError, match="empty column name"):
        read_trace(tmp_path / "bad.csv")
