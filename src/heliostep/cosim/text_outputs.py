"""The String and Binary outputs of a run, reported beside the trace (which holds numbers only).

:class:`TextOutputs` reads every String output (FMI 2.0 and 3.0) and Binary output (FMI 3.0) of
the system's instances at the start and after every event (the only times they can change: they
are discrete) and keeps each value with the time it took it. The master puts them in its
statistics as ``text_outputs`` (so in ``metadata.json``): ``INSTANCE.VARIABLE`` -> a list of
``[time [s], value]``, Binary values as hexadecimal digits.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from heliostep.cosim.system import CoupledSystem

TEXT_TYPES = ("String", "Binary")


class TextOutputs:
    """The String and Binary outputs of ``system``'s instances, sampled where they may change."""

    def __init__(self, system: CoupledSystem):
        self.readers: list[tuple[str, Any, Any]] = []
        for unit in system.unit_list:
            for name in unit.info.outputs:
                kind = unit.info.variables[name].type
                if kind in TEXT_TYPES:
                    get, _, buffer = unit.fmu._typed(kind, [name])
                    self.readers.append((f"{unit.name}.{name}", get, buffer))
        #: INSTANCE.VARIABLE -> [[time [s], value], ...], a pair wherever the value changed
        self.values: dict[str, list[list[Any]]] = {}

    def sample(self, t: float) -> None:
        """Read every text output at ``t`` [s] and keep those that changed."""
        for name, get, buffer in self.readers:
            get()
            value = buffer[0]
            text = value.hex() if isinstance(value, bytes) else str(value)
            history = self.values.setdefault(name, [])
            if not history or history[-1][1] != text:
                history.append([float(t), text])
