"""What an FMI 2.0 and an FMI 3.0 Co-Simulation instance of a sampled component share.

:class:`CoSimulationInstanceBase` holds the version-independent part (messages, the one error path,
initialization, Real values, closing); each version gives its instantiation, its entry into
initialization mode, its setters and its ``DoStep``.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from heliostep.cosim.description import FMUInfo, _extract, convert_value
from heliostep.cosim.instance import FMIError, _by_environment, _environment_ids
from heliostep.errors import InputError

__all__ = ["CoSimulationInstanceBase"]


class CoSimulationInstanceBase:
    """One instance of a Co-Simulation FMU, every FMI error an :class:`~heliostep.cosim.fmi.FMIError`
    naming the instance, the function, the time and the FMU's messages; a subclass per FMI version.

    Parameters
    ----------
    info : FMUInfo
        The FMU.
    name : str
        The instance's name (its log messages and errors say it).
    parameters : Mapping[str, object]
        Parameter values by name, set in initialization mode (each converted to the variable's type).
    """

    #: the prefix of the version's FMI function names ("fmi2", "fmi3")
    _FMI = ""
    #: the version's name of a 64-bit floating point variable's type ("Real", "Float64"): its set/get functions
    _REAL = ""
    #: how the version's step says the FMU asks to terminate (in the run's termination reason)
    TERMINATION = ""

    def __init__(self, info: FMUInfo, name: str, parameters: Mapping[str, object]):
        self.info, self.name = info, name
        self.messages: deque[str] = deque(maxlen=50)
        self.time = float("nan")
        self.last_successful_time: float | None = None  # where a step that asked to terminate ended [s]
        self._environment = next(_environment_ids)
        _by_environment[self._environment] = self  # the logger routes by this
        self._slave: Any = None
        self._parameters = dict(parameters)

    def _new_slave(self, slave_class: Callable[..., Any]) -> Any:
        """fmpy's slave of the version (``FMU2Slave``, ``FMU3Slave``): the FMU extracted, its binary loaded."""
        return slave_class(
            guid=self.info.guid,
            unzipDirectory=_extract(self.info.path),
            modelIdentifier=self.info.model_identifier,
            instanceName=self.name,
        )

    def _do(self, function: str, call: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        self.messages.clear()
        try:
            return call(*args, **kwargs)
        except Exception as exc:  # fmpy's FMICallException and the like
            raise FMIError(function, self.name, f"failure ({exc})", self.messages, self.time) from None

    def _enter_initialization_mode(self, start_time: float, stop_time: float) -> None:
        """The version's calls into initialization mode, with the start and stop time [s]."""
        raise NotImplementedError

    def _setter(self, name: str) -> str:
        """The name of fmpy's slave method that sets the variable ``name`` (``setReal``, ``setInt64``, ...)."""
        raise NotImplementedError

    def initialize(self, start_time: float, stop_time: float, inputs: Mapping[str, float]) -> None:
        """Into initialization mode (start and stop time [s]), parameters and inputs set, ExitInitializationMode."""
        variables = self.info.variables
        self.time = start_time
        self._enter_initialization_mode(start_time, stop_time)
        for name, value in self._parameters.items():
            if name not in variables or variables[name].causality != "parameter":
                known = ", ".join(v for v in variables if variables[v].causality == "parameter")
                raise InputError(
                    f"{self.name} ({self.info.path.name}) has no parameter {name!r}; its parameters: {known}"
                )
            self._set(name, convert_value(variables[name], value))
        for name, value in inputs.items():
            self._set(name, value)
        self._do(f"{self._FMI}ExitInitializationMode", self._slave.exitInitializationMode)

    def _set(self, name: str, value: Any) -> None:
        method = self._setter(name)
        self._do(
            f"{self._FMI}S{method[1:]}",
            getattr(self._slave, method),
            [self.info.variables[name].value_reference],
            [value],
        )

    def real_writer(self, names: Sequence[str]) -> Callable[[Sequence[float]], None]:
        """A setter of the Real (FMI 3.0: Float64) variables ``names``: called with their values, in that order."""
        refs = [self.info.variables[n].value_reference for n in names]
        setter = getattr(self._slave, f"set{self._REAL}")
        function = f"{self._FMI}Set{self._REAL}"

        def write(values: Sequence[float]) -> None:
            self._do(function, setter, refs, [float(v) for v in values])

        return write

    def real_reader(self, names: Sequence[str]) -> Callable[[], list[float]]:
        """A getter of the Real (FMI 3.0: Float64) variables ``names``: their values, in that order."""
        refs = [self.info.variables[n].value_reference for n in names]
        getter = getattr(self._slave, f"get{self._REAL}")
        function = f"{self._FMI}Get{self._REAL}"

        def read() -> list[float]:
            return list(self._do(function, getter, refs))

        return read

    def real_getter(self, names: Sequence[str], values: np.ndarray) -> Callable[[], None]:
        """A getter of the Real (FMI 3.0: Float64) variables ``names`` into ``values`` (a float64 vector, in place)."""
        read = self.real_reader(names)

        def get() -> None:
            values[:] = read()

        return get

    def real_setter(self, names: Sequence[str], values: np.ndarray) -> Callable[[], None]:
        """A setter of the Real (FMI 3.0: Float64) variables ``names`` from ``values`` (a float64 vector, read at
        each call)."""
        write = self.real_writer(names)

        def put() -> None:
            write(values.tolist())

        return put

    def do_step(self, to_time: float) -> bool:
        """DoStep from the instance's time to ``to_time`` [s]; whether the FMU asks to terminate the simulation."""
        raise NotImplementedError

    def close(self) -> None:
        """Terminate and FreeInstance (errors ignored: the run's own error, if any, is what counts), the
        binary unloaded once: fmpy's ``freeInstance`` unloads it itself, so only where that failed is it
        unloaded here (a second unload would take it from another instance of the same FMU)."""
        slave, self._slave = self._slave, None
        if slave is None:
            return
        try:
            slave.terminate()
        except Exception:  # noqa: BLE001 - closing after a failure must not hide it
            pass
        try:
            slave.freeInstance()
        except Exception:  # noqa: BLE001
            try:
                slave.freeLibrary()
            except Exception:  # noqa: BLE001
                pass
