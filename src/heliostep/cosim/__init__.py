"""Co-simulation of FMI 2.0 Model Exchange FMUs: FMI import and the master.

Owns everything FMI: :mod:`~heliostep.cosim.fmi` (the only ctypes code of heliostep:
modelDescription, binaries, calls), :mod:`~heliostep.cosim.master` (N FMUs on one CVODE)
and :mod:`~heliostep.cosim.signals` (the connections, input signals and solver settings it
consumes). It imports nothing of heliostep but :mod:`heliostep.errors`: no scenario, drive or
results type reaches it, so it serves any set of Model Exchange FMUs.
"""

from heliostep.cosim.fmi import FMIError, FMUInfo, read_fmu
from heliostep.cosim.master import CoSimulation, MasterResult, SimulationError
from heliostep.cosim.signals import Connection, PiecewiseConstant, SolverOptions

__all__ = ["CoSimulation", "Connection", "FMIError", "FMUInfo", "MasterResult", "PiecewiseConstant",
           "SimulationError", "SolverOptions", "read_fmu"]
