"""Typed access to the variables of a Model Exchange instance: get, set, read, write and link by name.

:class:`VariableAccess` reads and sets variables with the fmi2-shaped function of their type, builds
the readers, writers and connection copies the master uses, sets parameters by name and moves the
states at addresses; the life cycle and the error path are
:class:`~heliostep.cosim.instance.ModelExchangeBase`'s.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from heliostep.cosim import watch
from heliostep.cosim.description import FMUInfo, VariableInfo, convert_value
from heliostep.errors import InputError

#: ctypes element type and numpy dtype of the values of each FMI type, and its get/set functions
_TYPES = {
    "Real": (ctypes.c_double, np.float64, "fmi2GetReal", "fmi2SetReal"),
    "Integer": (ctypes.c_int, np.int32, "fmi2GetInteger", "fmi2SetInteger"),
    "Enumeration": (ctypes.c_int, np.int32, "fmi2GetInteger", "fmi2SetInteger"),
    "Boolean": (ctypes.c_int, np.int32, "fmi2GetBoolean", "fmi2SetBoolean"),
}


class VariableAccess:
    """Variables of one FMU instance by name or value reference, with the function of their type.

    The methods here call the FMU through ``_call`` (any FMI function, status checked),
    ``_check`` and ``_hot`` (the hot-path calls taking addresses) and ``_component``, which
    :class:`~heliostep.cosim.instance.ModelExchangeBase` provides.
    """

    info: FMUInfo
    index: int  # the instance's position in the master's order (for a supervisor's record)
    time: float  # the instance's current time [s]
    n_states: int
    n_event_indicators: int
    _component: Any
    _hot: dict[str, Callable[..., int]]

    if TYPE_CHECKING:

        def _call(self, function: str, *args: Any) -> int: ...

        def _check(self, function: str, status: int) -> None: ...

    @staticmethod
    def _pointer(array: np.ndarray, ctype: Any = ctypes.c_double) -> Any:
        return array.ctypes.data_as(ctypes.POINTER(ctype))

    @staticmethod
    def _vrs(value_references: Iterable[int]) -> tuple[Any, int]:
        from fmpy.fmi2 import fmi2ValueReference

        refs = list(value_references)
        return (fmi2ValueReference * len(refs))(*refs), len(refs)

    def link(
        self,
        outputs: list[str],
        target: VariableAccess,
        inputs: list[str],
        transforms: list[tuple[float, float] | None] | None = None,
    ) -> Callable[[], None]:
        """A call that copies this instance's ``outputs`` to ``target``'s ``inputs``.

        Real variables go through one buffer with the hot-path calls; the others in groups of one
        (source type, target type), each end with the calls of its type (fmi2Get/SetInteger,
        fmi2Get/SetBoolean, fmi2Get/SetString; an FMI 3.0 instance's own typed calls), the values
        converted by numpy as they are copied (the caller has checked that connected variables
        have compatible types). ``transforms`` (per pair, None for none) are (factor, offset) applied to
        a Real value on its way: ``factor * value + offset``.
        """
        types = [self.info.variable(name).type for name in outputs]
        transform = _transformer(transforms or [None] * len(outputs))
        if all(t == "Real" for t in types):
            source_vrs = np.array(self.value_references(outputs), dtype=np.uint32)
            target_vrs = np.array(target.value_references(inputs), dtype=np.uint32)
            buffer = np.zeros(len(outputs))
            n = len(outputs)
            source_address, target_address = source_vrs.ctypes.data, target_vrs.ctypes.data
            buffer_address = buffer.ctypes.data
            source_index, target_index = self.index, target.index

            def copy() -> None:
                watch.note(source_index, "fmi2GetReal", self.time)
                self._check("fmi2GetReal", self._hot["fmi2GetReal"](self._component, source_address, n, buffer_address))
                if transform is not None:
                    transform(buffer)
                watch.note(target_index, "fmi2SetReal", target.time)
                target._check(
                    "fmi2SetReal", target._hot["fmi2SetReal"](target._component, target_address, n, buffer_address)
                )

            # the arrays must outlive the closure's addresses
            copy.keep = (source_vrs, target_vrs, buffer)  # type: ignore[attr-defined]
            return copy
        groups = []
        kinds = list(zip(types, [target.info.variable(name).type for name in inputs]))
        for kind in dict.fromkeys(kinds):  # one group per (source type, target type)
            pairs = [(o, i) for o, i, k in zip(outputs, inputs, kinds) if k == kind]
            scaled = _transformer([t for t, k in zip(transforms or [None] * len(kinds), kinds) if k == kind])
            groups.append(
                (self._typed(kind[0], [o for o, _ in pairs]), target._typed(kind[1], [i for _, i in pairs]), scaled)
            )

        def copy_typed() -> None:
            for (get, _, get_buffer), (_, put, put_buffer), scaled in groups:
                get()
                put_buffer[:] = get_buffer
                if scaled is not None:  # (Real ends only: the connection graph checks it)
                    scaled(put_buffer)
                put()

        return copy_typed

    def _typed(self, kind: str, names: list[str]) -> tuple[Callable[[], None], Callable[[], None], np.ndarray]:
        """(get, set, buffer) for variables of one type: the calls read into / write from buffer."""
        if kind == "String":
            refs = self.value_references(names)
            texts = np.array([""] * len(names), dtype=object)

            def get_texts() -> None:
                texts[:] = self.get_string(refs)

            def put_texts() -> None:
                self.set_string(refs, list(texts))

            return get_texts, put_texts, texts
        if kind not in _TYPES:
            raise InputError(f"{self.info.path}: {', '.join(names)}: {kind} variables cannot be exchanged")
        ctype, dtype, getter, setter = _TYPES[kind]
        vrs, n = self._vrs(self.value_references(names))
        buffer = np.zeros(n, dtype=dtype)
        pointer = self._pointer(buffer, ctype)

        def get() -> None:
            self._call(getter, vrs, n, pointer)

        def put() -> None:
            self._call(setter, vrs, n, pointer)

        return get, put, buffer

    # ------------------------------------------------------------------ the states at addresses (the hot path)
    def set_states_at(self, address: int) -> None:
        """Set the continuous states from ``n_states`` doubles at ``address``."""
        watch.note(self.index, "fmi2SetContinuousStates", self.time)
        self._check(
            "fmi2SetContinuousStates", self._hot["fmi2SetContinuousStates"](self._component, address, self.n_states)
        )

    def get_states_at(self, address: int) -> None:
        """The continuous states into ``n_states`` doubles at ``address``."""
        watch.note(self.index, "fmi2GetContinuousStates", self.time)
        self._check(
            "fmi2GetContinuousStates", self._hot["fmi2GetContinuousStates"](self._component, address, self.n_states)
        )

    def get_derivatives_at(self, address: int) -> None:
        """The state derivatives into ``n_states`` doubles at ``address``."""
        watch.note(self.index, "fmi2GetDerivatives", self.time)
        self._check("fmi2GetDerivatives", self._hot["fmi2GetDerivatives"](self._component, address, self.n_states))

    def get_event_indicators_at(self, address: int) -> None:
        """The event indicators into ``n_event_indicators`` doubles at ``address``."""
        watch.note(self.index, "fmi2GetEventIndicators", self.time)
        self._check(
            "fmi2GetEventIndicators",
            self._hot["fmi2GetEventIndicators"](self._component, address, self.n_event_indicators),
        )

    def value_references(self, names: Iterable[str]) -> list[int]:
        return [self.info.variable(name).value_reference for name in names]

    def set_parameters(self, values: Mapping[str, object]) -> None:
        """Set parameters by name, each with the function of its type (Real, Integer,
        Enumeration, Boolean, String): before initialization, or tunable ones in event mode."""
        for kind, items in self._parameters_by_type(values, lambda variable: variable.type).items():
            refs, data = [variable.value_reference for _, variable, _ in items], [value for _, _, value in items]
            if kind == "Real":
                self.set_real(refs, data)
            elif kind in ("Integer", "Enumeration"):
                self.set_integer(refs, data)
            elif kind == "Boolean":
                self.set_boolean(refs, data)
            else:
                self.set_string(refs, data)

    def _parameters_by_type(
        self, values: Mapping[str, object], type_of: Callable[[VariableInfo], str]
    ) -> dict[str, list[tuple[str, VariableInfo, Any]]]:
        """Parameter values by name grouped by their variable's type (``type_of``: FMI 2.0's or 3.0's),
        each ``(name, variable, value converted to its type)``, in the order given; InputError naming
        the FMU and every unknown name, with the valid ones."""
        valid = self.info.parameters
        unknown = [name for name in values if name not in valid]
        if unknown:
            raise InputError(
                f"{self.info.path}: {self.info.model_name} has no parameter "
                f"{', '.join(map(repr, unknown))}; valid parameters: {', '.join(valid)}"
            )
        by_type: dict[str, list[tuple[str, VariableInfo, Any]]] = {}
        for name, value in values.items():
            variable = self.info.variables[name]
            by_type.setdefault(type_of(variable), []).append((name, variable, convert_value(variable, value)))
        return by_type

    def set_real(self, value_references: Iterable[int], values: Iterable[float]) -> None:
        vrs, n = self._vrs(value_references)
        data = np.ascontiguousarray(np.fromiter(values, dtype=float, count=n))
        self._call("fmi2SetReal", vrs, n, self._pointer(data))

    def get_real(self, value_references: Iterable[int]) -> np.ndarray:
        vrs, n = self._vrs(value_references)
        out = np.zeros(n)
        self._call("fmi2GetReal", vrs, n, self._pointer(out))
        return out

    def set_integer(self, value_references: Iterable[int], values: Iterable[int]) -> None:
        vrs, n = self._vrs(value_references)
        data = np.ascontiguousarray(np.fromiter(values, dtype=np.int32, count=n))
        self._call("fmi2SetInteger", vrs, n, self._pointer(data, ctypes.c_int))

    def get_integer(self, value_references: Iterable[int]) -> np.ndarray:
        vrs, n = self._vrs(value_references)
        out = np.zeros(n, dtype=np.int32)
        self._call("fmi2GetInteger", vrs, n, self._pointer(out, ctypes.c_int))
        return out

    def set_boolean(self, value_references: Iterable[int], values: Iterable[bool]) -> None:
        vrs, n = self._vrs(value_references)
        data = np.ascontiguousarray(np.fromiter((bool(v) for v in values), dtype=np.int32, count=n))
        self._call("fmi2SetBoolean", vrs, n, self._pointer(data, ctypes.c_int))

    def get_boolean(self, value_references: Iterable[int]) -> np.ndarray:
        vrs, n = self._vrs(value_references)
        out = np.zeros(n, dtype=np.int32)
        self._call("fmi2GetBoolean", vrs, n, self._pointer(out, ctypes.c_int))
        return out.astype(bool)

    def set_string(self, value_references: Iterable[int], values: Iterable[str]) -> None:
        vrs, n = self._vrs(value_references)
        data = (ctypes.c_char_p * n)(*[str(v).encode("utf-8") for v in values])
        self._call("fmi2SetString", vrs, n, data)

    def get_string(self, value_references: Iterable[int]) -> list[str]:
        vrs, n = self._vrs(value_references)
        out = (ctypes.c_char_p * n)()
        self._call("fmi2GetString", vrs, n, out)
        return [(v or b"").decode("utf-8", "replace") for v in out]

    def reader(self, names: Iterable[str]) -> Callable[[], np.ndarray]:
        """A fast getter of the named variables (Real, Integer, Enumeration, Boolean):
        ``read() -> ndarray`` of floats in the order of ``names`` (no per-call lookup)."""
        names = list(names)
        types = [self.info.variable(name).type for name in names]
        out = np.zeros(len(names))
        if all(t == "Real" for t in types):
            vrs, n = self._vrs(self.value_references(names))
            pointer = self._pointer(out)

            def read() -> np.ndarray:
                self._call("fmi2GetReal", vrs, n, pointer)
                return out.copy()

            return read
        groups = []
        for kind in dict.fromkeys(types):
            index = np.array([k for k, t in enumerate(types) if t == kind], dtype=int)
            get, _, buffer = self._typed(kind, [names[k] for k in index])
            groups.append((index, get, buffer))

        def read_typed() -> np.ndarray:
            for index, get, buffer in groups:
                get()
                out[index] = buffer
            return out.copy()

        return read_typed

    def writer(self, names: Iterable[str]) -> Callable[[Any], None]:
        """A fast setter of the named variables: ``write(values)`` (floats, converted to each
        variable's type: Integer rounded, Boolean true when non-zero)."""
        names = list(names)
        types = [self.info.variable(name).type for name in names]
        groups = []
        for kind in dict.fromkeys(types):
            index = np.array([k for k, t in enumerate(types) if t == kind], dtype=int)
            _, put, buffer = self._typed(kind, [names[k] for k in index])
            groups.append((index, put, buffer, kind))

        def write(values) -> None:
            values = np.asarray(values, dtype=float)
            for index, put, buffer, kind in groups:
                if kind == "Real":
                    buffer[:] = values[index]
                elif kind == "Boolean":
                    buffer[:] = values[index] != 0
                else:
                    buffer[:] = np.rint(values[index])
                put()

        return write


def _transformer(transforms: list[tuple[float, float] | None]) -> Callable[[np.ndarray], None] | None:
    """What applies ``transforms`` (per value: (factor, offset), or None) to a buffer of Real values in place:
    ``factor * value + offset`` at the transformed places only (the others, and (1, 0), left as they are);
    None when nothing is transformed."""
    places = [k for k, t in enumerate(transforms) if t is not None and t != (1.0, 0.0)]
    if not places:
        return None
    index = np.array(places)
    factors = np.array([transforms[k][0] for k in places])  # type: ignore[index]
    offsets = np.array([transforms[k][1] for k in places])  # type: ignore[index]

    def transform(buffer: np.ndarray) -> None:
        buffer[index] = factors * buffer[index] + offsets

    return transform
