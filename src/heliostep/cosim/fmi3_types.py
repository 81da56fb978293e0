"""FMI 3.0 variables of every type, and array variables element by element.

:func:`fmi3_variables` names every scalar and every element of an array (``a[2,3]``: 1-based,
row-major, as an FMI 2.0 export of a Modelica model names its scalars, so traces compare across
versions). Float64, Int32 and Boolean scalars keep their own value reference; every other variable
gets a *slot*, a value reference past the FMU's own that the adapter (``c/fmi3_adapter.c``) resolves
to the typed call and element, as a double, so the compiled kernel reaches every numeric type.
:func:`typed_access` gets and sets variables of one type with their own fmi3 function;
:func:`integer_range` gives the range connections are checked against.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from heliostep.errors import InputError

#: FMI 3.0 type -> (ctypes type of one value, numpy dtype, the adapter's type code (fmi3_adapter.c))
FMI3_TYPES: dict[str, tuple[Any, Any, int]] = {
    "Float64": (ctypes.c_double, np.float64, 0),
    "Float32": (ctypes.c_float, np.float32, 1),
    "Int8": (ctypes.c_int8, np.int8, 2),
    "UInt8": (ctypes.c_uint8, np.uint8, 3),
    "Int16": (ctypes.c_int16, np.int16, 4),
    "UInt16": (ctypes.c_uint16, np.uint16, 5),
    "Int32": (ctypes.c_int32, np.int32, 6),
    "UInt32": (ctypes.c_uint32, np.uint32, 7),
    "Int64": (ctypes.c_int64, np.int64, 8),
    "UInt64": (ctypes.c_uint64, np.uint64, 9),
    "Enumeration": (ctypes.c_int64, np.int64, 8),  # FMI 3.0 enumerations are got and set as Int64
    "Boolean": (ctypes.c_bool, np.bool_, 10),
    "String": (ctypes.c_char_p, object, -1),
    "Binary": (ctypes.c_void_p, object, -1),
}

#: the FMI 3.0 scalar types the adapter passes straight on, and the master's (FMI 2.0's) names for them
NATIVE = {"Float64": "Real", "Int32": "Integer", "Boolean": "Boolean"}

#: FMI 3.0 (and FMI 2.0) integer type -> its range of values
_RANGES = {
    "Int8": (-(2**7), 2**7 - 1),
    "UInt8": (0, 2**8 - 1),
    "Int16": (-(2**15), 2**15 - 1),
    "UInt16": (0, 2**16 - 1),
    "Int32": (-(2**31), 2**31 - 1),
    "UInt32": (0, 2**32 - 1),
    "Int64": (-(2**63), 2**63 - 1),
    "UInt64": (0, 2**64 - 1),
    "Enumeration": (-(2**63), 2**63 - 1),
}


def integer_range(variable: Any) -> tuple[int, int] | None:
    """The range of an integer variable's values (FMI 2.0 Integer and Enumeration: Int32), else None."""
    if variable.fmi3_type:
        return _RANGES.get(variable.fmi3_type)
    return _RANGES["Int32"] if variable.type in ("Integer", "Enumeration") else None


def type_label(variable: Any) -> str:
    """The variable's type as its FMI version names it: "Int8 (FMI 3.0)"; FMI 2.0's plain ("Integer")."""
    return f"{variable.fmi3_type} (FMI 3.0)" if variable.fmi3_type else variable.type


def element_names(name: str, shape: Sequence[int]) -> list[str]:
    """The names of an array's elements in row-major order, 1-based: ``a[1,1]``, ``a[1,2]`` ..."""
    return [f"{name}[{','.join(str(i + 1) for i in index)}]" for index in np.ndindex(*shape)]


def _starts(fmi3_type: str, start: Any, size: int) -> list[float | str | None]:
    """The start value of each element: numbers as floats, Boolean as 0/1, String and Binary (hex) as text."""
    if start is None:
        return [None] * size
    if fmi3_type in ("String", "Binary"):
        return [str(start)] * size
    words = str(start).split()
    if len(words) != size:
        words = (words * size)[:size] if words else []
    values: list[float | str | None] = []
    for word in words:
        if fmi3_type == "Boolean":
            values.append(float(word.lower() in ("true", "1")))
        else:
            try:
                values.append(float(word))
            except ValueError:
                values.append(None)
    return values or [None] * size


def fmi3_variables(description) -> tuple[dict[str, dict[str, Any]], list[str], int, dict[str, list[str]]]:
    """The variables of fmpy's FMI 3.0 ``description`` element-wise: (name -> the fields of its
    :class:`~heliostep.cosim.description.VariableInfo`, the states' names, the number of event
    indicators, output -> the inputs it depends on directly)."""
    next_slot = 1 + max((v.valueReference for v in description.modelVariables), default=0)
    variables: dict[str, dict[str, Any]] = {}
    names_of: dict[int, list[str]] = {}  # FMI 3.0 value reference -> the names of its scalar or elements
    for v in description.modelVariables:
        shape = tuple(getattr(v, "shape", None) or ())
        size = int(np.prod(shape)) if shape else 1
        names = element_names(v.name, shape) if shape else [v.name]
        starts = _starts(v.type, v.start, size)
        master_type = NATIVE.get(v.type, v.type)
        for k, name in enumerate(names):
            if not shape and v.type in NATIVE:
                reference = v.valueReference
            else:
                reference, next_slot = next_slot, next_slot + 1
            variables[name] = dict(
                name=name,
                value_reference=reference,
                type=master_type,
                causality=v.causality,
                variability=v.variability,
                unit=v.unit or getattr(getattr(v, "declaredType", None), "unit", None) or "",
                start=starts[k],
                description=v.description or "",
                fmi3_type=v.type,
                fmi3_reference=v.valueReference,
                element=k if shape else -1,
                size=size,
            )
        names_of[v.valueReference] = names
    states = [name for d in description.derivatives for name in names_of[d.variable.derivative.valueReference]]
    n_indicators = sum(len(names_of[u.variable.valueReference]) for u in description.eventIndicators or [])
    inputs = [name for name, fields in variables.items() if fields["causality"] == "input"]
    feedthrough: dict[str, list[str]] = {}
    for unknown in description.outputs:
        dependencies = unknown.dependencies
        depends = (
            inputs
            if dependencies is None
            else [n for d in dependencies if d.causality == "input" for n in names_of[d.valueReference]]
        )
        for name in names_of[unknown.variable.valueReference]:
            feedthrough[name] = list(depends)
    return variables, states, n_indicators, feedthrough


def slot_table(variables: Mapping[str, Any]) -> tuple[int, np.ndarray]:
    """(the first slot, the adapter's table: per slot its type code, FMI 3.0 value reference,
    element and array size, as int64 rows) for the adapter's ``fmi2GetReal``/``fmi2SetReal``."""
    slotted = sorted(
        (v for v in variables.values() if v.through_slot and FMI3_TYPES[v.fmi3_type][2] >= 0),
        key=lambda v: v.value_reference,
    )
    if not slotted:
        return 0xFFFFFFFF, np.zeros((1, 4), dtype=np.int64)
    base = slotted[0].value_reference
    table = np.full((slotted[-1].value_reference - base + 1, 4), -1, dtype=np.int64)
    for v in slotted:
        table[v.value_reference - base] = (FMI3_TYPES[v.fmi3_type][2], v.fmi3_reference, max(v.element, 0), v.size)
    return base, table


def _function(fmi3_type: str, setter: bool) -> str:
    return ("fmi3Set" if setter else "fmi3Get") + ("Int64" if fmi3_type == "Enumeration" else fmi3_type)


_VALUES = ctypes.CFUNCTYPE(
    ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p, ctypes.c_size_t
)
_BINARY = ctypes.CFUNCTYPE(
    ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t
)

#: every typed fmi3Get/fmi3Set function -> its ctypes prototype
TYPED_CALLS = {
    _function(t, setter): (_BINARY if t == "Binary" else _VALUES)
    for t in FMI3_TYPES
    if t != "Enumeration"
    for setter in (False, True)
}


def typed_access(fmu: Any, names: Sequence[str]) -> tuple[Callable[[], None], Callable[[], None], np.ndarray]:
    """(get, set, buffer) for the named variables of ``fmu`` (a
    :class:`~heliostep.cosim.fmi3.ModelExchange3Instance`), all of one FMI 3.0 type: ``get()`` reads them into
    ``buffer``, ``set()`` writes ``buffer`` to them, each with one call of the type's own function on
    the FMI 3.0 value references (a whole array read, or written with its other elements as they are)."""
    variables = [fmu.info.variable(name) for name in names]
    fmi3_type = variables[0].fmi3_type
    if any(v.fmi3_type != fmi3_type for v in variables):
        raise InputError(f"{fmu.info.path}: {', '.join(names)}: not of one FMI 3.0 type")
    ctype, dtype, _ = FMI3_TYPES[fmi3_type]
    references = list(dict.fromkeys(v.fmi3_reference for v in variables))
    sizes = {v.fmi3_reference: v.size for v in variables}
    offsets = dict(zip(references, np.cumsum([0] + [sizes[r] for r in references])))
    index = np.array([offsets[v.fmi3_reference] + max(v.element, 0) for v in variables], dtype=int)
    total = int(sum(sizes.values()))
    whole = len(set(index.tolist())) == total  # every element of every array named: set without reading
    vrs = (ctypes.c_uint32 * len(references))(*references)
    buffer = np.zeros(len(names), dtype=dtype) if dtype is not object else np.array([None] * len(names), dtype=object)
    start_of = {(v.fmi3_reference, max(v.element, 0)): v.start for v in fmu.info.variables.values() if v.fmi3_type}
    starts = [start_of.get((r, e)) for r in references for e in range(sizes[r])]
    if fmi3_type in ("String", "Binary"):
        return _text_access(fmu, fmi3_type, vrs, len(references), total, index, buffer, whole)
    values = np.zeros(total, dtype=dtype)
    pointer, getter, setter = values.ctypes.data, _function(fmi3_type, False), _function(fmi3_type, True)

    def get() -> None:
        fmu._call(getter, vrs, len(references), pointer, total)
        buffer[:] = values[index]

    def put() -> None:
        if not whole:  # the array's other elements: as they are (before initialization: their start values)
            if fmu.mode == "instantiated":
                values[:] = [0 if s is None else s for s in starts]
            else:
                fmu._call(getter, vrs, len(references), pointer, total)
        values[index] = buffer
        fmu._call(setter, vrs, len(references), pointer, total)

    return get, put, buffer


def _text_access(fmu, fmi3_type, vrs, n_references, total, index, buffer, whole):
    """typed_access for String (Python str) and Binary (bytes) variables."""
    if not whole:
        raise InputError(f"{fmu.info.path}: elements of {fmi3_type} arrays are exchanged only whole")
    getter, setter = _function(fmi3_type, False), _function(fmi3_type, True)
    pointers = (ctypes.c_void_p * total)()
    lengths = (ctypes.c_size_t * total)()

    def get() -> None:
        texts: list[str] | list[bytes]
        if fmi3_type == "String":
            fmu._call(getter, vrs, n_references, pointers, total)
            texts = [ctypes.string_at(p).decode("utf-8", "replace") if p else "" for p in pointers]
        else:
            fmu._call(getter, vrs, n_references, lengths, pointers, total)
            texts = [ctypes.string_at(p, n) if p else b"" for p, n in zip(pointers, lengths)]
        for j, k in enumerate(index):
            buffer[j] = texts[k]

    def put() -> None:
        data = [b""] * total
        for j, k in enumerate(index):
            value = buffer[j]
            data[k] = value if isinstance(value, bytes) else str(value).encode("utf-8")
        keep = [ctypes.create_string_buffer(d, len(d) + 1) for d in data]
        for k, block in enumerate(keep):
            pointers[k] = ctypes.addressof(block)
            lengths[k] = len(data[k])
        if fmi3_type == "String":
            fmu._call(setter, vrs, n_references, pointers, total)
        else:
            fmu._call(setter, vrs, n_references, lengths, pointers, total)

    return get, put, buffer
