"""Reading Modelica tools' result files (``.mat``, Dymola and OpenModelica) as traces.

Details: docs/compare.md, ``heliostep.results.trace.modelica``.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep.errors import InputError
from heliostep.input_files import MAX_ARCHIVE_BYTES, check_input_file
from heliostep.results.trace.format import TIME, check_time

__all__ = ["MAT_SUFFIX", "read_modelica_mat", "unit_of_description"]

MAT_SUFFIX = ".mat"
_UNIT = re.compile(r"\[([^\[\]|]*)(?:\|[^\[\]]*)?\]\s*$")
_TIME_NAMES = ("time", "Time")


def unit_of_description(description: str) -> str | None:
    """The unit at the end of a Modelica result file's description (``"Angle [rad|deg]"`` -> ``rad``)."""
    found = _UNIT.search(description)
    unit = found.group(1).strip() if found else ""
    return unit or None


def _strings(matrix: np.ndarray, transposed: bool, path: Path, key: str) -> list[str]:
    """The rows (or, transposed, the columns) of a char matrix as stripped strings."""
    chars = np.asarray(matrix)
    if chars.ndim == 1:
        chars = chars.reshape(1, -1) if not transposed else chars.reshape(-1, 1)
    if chars.dtype.kind not in "US":
        raise InputError(f"{path}: {key!r} is not a character matrix")
    if transposed:
        chars = chars.T
    return ["".join(str(c) for c in row).replace("\x00", " ").strip() for row in chars]


def _matrix(contents: dict, key: str, path: Path, transposed: bool) -> np.ndarray:
    if key not in contents:
        raise InputError(f"{path}: no matrix {key!r} (a Modelica result file has Aclass, name, dataInfo, data_2)")
    values = np.atleast_2d(np.asarray(contents[key]))
    return values.T if transposed else values


def _load(path: Path) -> dict:
    from scipy.io import loadmat

    try:
        return loadmat(str(path), chars_as_strings=False, squeeze_me=False)
    except NotImplementedError as exc:  # MATLAB v7.3 (HDF5)
        raise InputError(f"{path}: unsupported MAT file ({exc}); expected MAT v4 or v5") from None
    except Exception as exc:  # scipy raises several types for damaged files
        raise InputError(f"{path}: cannot read as a MAT file: {exc}") from None


def read_modelica_mat(path: str | Path) -> tuple[pd.DataFrame, dict[str, str]]:
    """A Dymola / OpenModelica ``.mat`` result file as ``(table, metadata)``; see the module."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such file")
    check_input_file(path, "Modelica result", MAX_ARCHIVE_BYTES)
    contents = _load(path)
    if "Aclass" not in contents:
        raise InputError(f"{path}: no 'Aclass' matrix: not a Modelica result file (Dymola/OpenModelica layout)")
    aclass = _strings(contents["Aclass"], False, path, "Aclass")
    if not aclass or aclass[0] != "Atrajectory":
        raise InputError(f"{path}: Aclass {aclass!r}: expected 'Atrajectory' in its first row")
    transposed = len(aclass) > 3 and aclass[3] == "binTrans"
    names = _strings(contents.get("name", np.empty((0, 0), "U1")), transposed, path, "name")
    descriptions = (
        _strings(contents["description"], transposed, path, "description")
        if "description" in contents
        else [""] * len(names)
    )
    info = _matrix(contents, "dataInfo", path, transposed).astype(np.int64)
    if info.shape[0] != len(names) or info.shape[1] < 2:
        raise InputError(f"{path}: dataInfo has shape {info.shape}, expected ({len(names)}, 4)")
    data_2 = _matrix(contents, "data_2", path, transposed).astype(np.float64)
    data_1 = _matrix(contents, "data_1", path, transposed).astype(np.float64) if "data_1" in contents else None
    if data_2.shape[0] == 0:
        raise InputError(f"{path}: data_2 has no rows")
    time = data_2[:, 0].copy()
    check_time(time, str(path))
    columns: dict[str, np.ndarray] = {TIME: time}
    meta = {"source": "modelica-mat"}
    for k, (name, description) in enumerate(zip(names, descriptions)):
        values = _values(path, name, info[k], data_1, data_2, time)
        if name in _TIME_NAMES and info[k, 0] in (0, 2) and abs(info[k, 1]) == 1:
            name = TIME  # the abscissa (or a copy of it)
        if name in columns and name != TIME:
            raise InputError(f"{path}: variable {name!r} appears twice in 'name'")
        columns.setdefault(name, values)
        unit = unit_of_description(description)
        if unit:
            meta[f"unit.{name}"] = unit
    return pd.DataFrame(columns), meta


def _values(
    path: Path, name: str, info: np.ndarray, data_1: np.ndarray | None, data_2: np.ndarray, time: np.ndarray
) -> np.ndarray:
    """One variable's values on the rows of ``data_2``; a parameter (``data_1``) interpolated
    between its start and end values (constant in practice)."""
    matrix, column = int(info[0]), int(info[1])
    sign = -1.0 if column < 0 else 1.0
    j = abs(column) - 1
    if matrix in (0, 2):
        source = data_2
    elif matrix == 1 and data_1 is not None:
        source = data_1
    else:
        raise InputError(f"{path}: variable {name!r}: dataInfo names matrix {matrix}, which the file lacks")
    if not 0 <= j < source.shape[1]:
        raise InputError(f"{path}: variable {name!r}: dataInfo column {column} is outside data_{max(matrix, 2)}")
    if source is data_2:
        return sign * data_2[:, j]
    start, end = source[0, j], source[-1, j]
    if start == end or time[-1] == time[0]:
        return np.full(time.shape, sign * start)
    return sign * np.interp(time, [time[0], time[-1]], [start, end])
