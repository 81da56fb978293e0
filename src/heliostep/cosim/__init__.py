"""Co-simulation of FMUs: FMI import and the master (FMI 2.0 and 3.0, Model Exchange and Co-Simulation).

Owns everything FMI and the solver, and all of heliostep's ctypes: the FMU kinds
(:mod:`~heliostep.cosim.kinds`), reading (:mod:`~heliostep.cosim.description`), instances
(:mod:`~heliostep.cosim.instance`, :mod:`~heliostep.cosim.fmi`, :mod:`~heliostep.cosim.fmi3`,
:mod:`~heliostep.cosim.access`), connections and loops, the coupled system
(:mod:`~heliostep.cosim.system`), the integrator and the compiled kernel, and the master
(:mod:`~heliostep.cosim.master`). It imports nothing of heliostep but :mod:`heliostep.errors`,
:mod:`heliostep.paths` and :mod:`heliostep.toolchain`.
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
