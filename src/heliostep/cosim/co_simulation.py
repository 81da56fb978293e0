"""What an FMI 2.0 and an FMI 3.0 Co-Simulation instance of a sampled component share.

:class:`CoSimulationInstanceBase` holds the version-independent part (messages, the one error path,
initialization, Real values, closing); each version gives its instantiation, its entry into
initialization mode, its setters and its ``DoStep``.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Mapping, Sequence
from typing import Any

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

    def set_real(self, names: Sequence[str], values: Sequence[float]) -> None:
        """Set Real (FMI 3.0: Float64) variables by name."""
        refs = [self.info.variables[n].value_reference for n in names]
        self._do(
            f"{self._FMI}Set{self._REAL}", getattr(self._slave, f"set{self._REAL}"), refs, [float(v) for v in values]
        )

    def get_real(self, names: Sequence[str]) -> list[float]:
        """The values of Real (FMI 3.0: Float64) variables by name."""
        refs = [self.info.variables[n].value_reference for n in names]
        return list(self._do(f"{self._FMI}Get{self._REAL}", getattr(self._slave, f"get{self._REAL}"), refs))

    def do_step(self, to_time: float) -> bool:
        """DoStep from the instance's time to ``to_time`` [s]; whether the FMU asks to terminate the simulation."""
        raise NotImplementedError

    def close(self) -> None:
        """Terminate (errors ignored: the run's own error, if any, is what counts) and FreeInstance."""
        slave, self._slave = self._slave, None
        if slave is None:
            return
        for call in (slave.terminate, slave.freeInstance):
            try:
                call()
            except Exception:  # noqa: BLE001 - closing after a failure must not hide it
                pass
        try:
            slave.freeLibrary()
        except Exception:  # noqa: BLE001
            pass
