"""Co-simulation of FMI 2.0 Model Exchange FMUs: FMI import and the master.

Owns everything FMI and the solver. Its modules, each owning one thing:

- :mod:`~heliostep.cosim.description`: ``modelDescription.xml``, variable types, the up-front
  check of the platform binary;
- :mod:`~heliostep.cosim.fmi`: an FMU instance's life cycle, the calls on the integrator's hot
  path and the one FMI error path (:class:`FMIError`), per-instance logging, public accessors for
  C code (the component handle, function addresses);
  :mod:`~heliostep.cosim.access`: the typed access to its variables;
- :mod:`~heliostep.cosim.signals`: the connections, input signals and solver settings the master
  consumes; :mod:`~heliostep.cosim.connections`: connections checked, their propagation order,
  torn algebraic loops; :mod:`~heliostep.cosim.loops`: Newton on torn algebraic loops;
- :mod:`~heliostep.cosim.system`: the coupled system of a run (instances, links, loops,
  propagation, the states as one vector);
- :mod:`~heliostep.cosim.integrator`: the :class:`~heliostep.cosim.integrator.Integrator`
  protocol and CVODE on the compiled kernel or on Python callbacks;
  :mod:`~heliostep.cosim.sundials`: every SUNDIALS binding;
  :mod:`~heliostep.cosim.kernel` (with ``c/kernel.c``, ``c/kernel.h``): the compiled right-hand
  side, root function and the one loop over CVODE's internal steps;
- :mod:`~heliostep.cosim.rows`: the trace rows held or handed to a sink;
- :mod:`~heliostep.cosim.master`: the run (N FMUs on one CVODE, events, discrete exchange,
  terminateSimulation) behind :class:`CoSimulation`, every solution row shown to its
  :class:`~heliostep.cosim.master.SolutionMonitor`.

The ctypes code of heliostep is here (description, fmi, access, sundials, kernel, integrator,
system); nothing outside :mod:`heliostep.cosim` imports ctypes. It imports nothing of heliostep but
:mod:`heliostep.errors`, :mod:`heliostep.paths` and :mod:`heliostep.toolchain` (the kernel's
cache): no scenario, drive or results type reaches it, so it serves any set of Model Exchange FMUs.
"""

from heliostep.cosim.fmi import FMIError, FMUInfo, read_fmu
from heliostep.cosim.loops import LoopError
from heliostep.cosim.master import CoSimulation, MasterResult, SimulationError, SolutionMonitor
from heliostep.cosim.signals import Connection, PiecewiseConstant, SolverOptions

__all__ = [
    "CoSimulation",
    "Connection",
    "FMIError",
    "FMUInfo",
    "LoopError",
    "MasterResult",
    "PiecewiseConstant",
    "SimulationError",
    "SolutionMonitor",
    "SolverOptions",
    "read_fmu",
]
