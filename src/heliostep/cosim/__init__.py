"""Co-simulation of FMI 2.0 Model Exchange FMUs: FMI import and the master.

Owns everything FMI: :mod:`~heliostep.cosim.description` (``modelDescription.xml``, variable
types, the up-front check of the platform binary), :mod:`~heliostep.cosim.fmi` (the only
ctypes code of heliostep with the kernel: calls on instances of every variable type, per-instance logging),
:mod:`~heliostep.cosim.connections` (connections checked, their propagation order, torn
algebraic loops), :mod:`~heliostep.cosim.master` (N FMUs on one CVODE, discrete exchange at
events, terminateSimulation), :mod:`~heliostep.cosim.loops` (Newton on torn algebraic loops),
:mod:`~heliostep.cosim.signals` (the connections, input signals and solver settings it
consumes) and :mod:`~heliostep.cosim.kernel` (the compiled right-hand side, root function and
one-step loop, C called by CVODE directly). It imports nothing of
heliostep but :mod:`heliostep.errors`, :mod:`heliostep.paths` and :mod:`heliostep.toolchain` (the
kernel's cache): no scenario, drive or results type reaches it, so it serves any set of Model
Exchange FMUs.
"""

from heliostep.cosim.fmi import FMIError, FMUInfo, read_fmu
from heliostep.cosim.loops import LoopError
from heliostep.cosim.master import CoSimulation, MasterResult, SimulationError
from heliostep.cosim.signals import Connection, PiecewiseConstant, SolverOptions

__all__ = ["CoSimulation", "Connection", "FMIError", "FMUInfo", "LoopError", "MasterResult",
           "PiecewiseConstant", "SimulationError", "SolverOptions", "read_fmu"]
