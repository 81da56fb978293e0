"""The torque a motor can deliver: its holding torque and its pull-out torque against step rate.

Both co-simulated with the project's FMUs on a test bench (the mechanics FMU as a load inertia and
a brake), as a dynamometer measures them.

Details: docs/sizing.md, ``heliostep.run.speed_torque``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from heliostep.cosim import Connection, CoSimulation, PiecewiseConstant, SimulationError, SolverOptions, read_fmu
from heliostep.drive.sequencer import Sequencer
from heliostep.fmu.build import ensure_fmu
from heliostep.scenario.catalogue import MotorDrive

__all__ = [
    "BENCH_LOAD_INERTIA",
    "HOLD_STEPS",
    "SpeedTorqueCurve",
    "bench_fmus",
    "holding_torque",
    "pull_out_torque",
    "speed_torque_curve",
    "steps_kept",
]

#: The bench's load inertia on the motor shaft [kg.m2]: the paper's panel seen through its drive,
#: J_p / g^2 = 3.37 / (0.3 / 2.5e-3)^2 = 2.34e-4 (Table 2, docs/physics.md).
BENCH_LOAD_INERTIA = 3.37 / (0.3 / 2.5e-3) ** 2
#: The bench's ratio s / r (the mechanics FMU's lever arm over pinion radius).
BENCH_RATIO = 1200.0
#: Steps at the test rate after the ramp.
HOLD_STEPS = 40
#: The step rate a test's ramp starts from [full steps/s] (or the test rate, when lower).
START_RATE = 20.0
#: The ramp's inertia torque as a fraction of the holding torque (its acceleration).
RAMP_TORQUE_FRACTION = 0.02
#: The load's rise with the rotor held: levels and time [s].
LOAD_LEVELS = 50
LOAD_RAMP_TIME = 0.5
#: Settling under a static load before the rotor's position is judged [s].
SETTLE_TIME = 0.1
#: CVODE's internal steps between two output times in a bench test (a rotor that runs away needs more).
MAX_SOLVER_STEPS = 20_000
#: The bench's output interval [s] (the step limit above applies per interval).
OUTPUT_INTERVAL = 0.01
#: Steps at the end of the hold at which the rotor's lag behind the command is judged.
JUDGED_STEPS = 10
_DRIVE_CONNECTIONS = (
    Connection("motor.tau", "mechanics.tau"),
    Connection("mechanics.theta", "motor.theta"),
    Connection("mechanics.omega", "motor.omega"),
)


@dataclass(frozen=True)
class SpeedTorqueCurve:
    """A motor's pull-out torque against step rate at one current and bus.

    Attributes
    ----------
    current : float
        Reference phase current [A].
    holding_torque : float
        Co-simulated static holding torque [N.m] (one phase on).
    step_rates : ndarray
        [full steps/s].
    pull_out_torques : ndarray
        [N.m], one per rate.
    mode : str
        The sequencer mode; ``microsteps`` its microsteps per full step.
    """

    current: float
    holding_torque: float
    step_rates: np.ndarray
    pull_out_torques: np.ndarray
    mode: str = "one-phase-on"
    microsteps: int = 1
    notes: list[str] = field(default_factory=list)

    def at(self, step_rate: float) -> float:
        """The pull-out torque at ``step_rate`` [N.m]: interpolated, the lowest rate's below it."""
        return float(np.interp(step_rate, self.step_rates, self.pull_out_torques))

    def record(self) -> dict:
        """As JSON: rates [steps/s], torques [N.m]."""
        return {
            "current_A": self.current,
            "holding_torque_Nm": self.holding_torque,
            "mode": self.mode,
            "microsteps": self.microsteps,
            "step_rates_per_s": [float(f) for f in self.step_rates],
            "pull_out_torques_Nm": [float(t) for t in self.pull_out_torques],
        }


def bench_fmus(fmu_paths: Mapping[str, Path] | None = None) -> dict[str, Path]:
    """The bench's FMUs (``motor``: StepperMotor, ``mechanics``: PanelMechanics), built when needed."""
    if fmu_paths is not None:
        return dict(fmu_paths)
    return {"motor": ensure_fmu("StepperMotor"), "mechanics": ensure_fmu("PanelMechanics")}


def _ramp_step_times(step_rate: float, drive: MotorDrive, current: float, inertia: float, start: float) -> np.ndarray:
    """Step instants [s] from ``start``: a constant-acceleration ramp up to ``step_rate``, then HOLD_STEPS."""
    rate0 = min(step_rate, START_RATE)
    alpha = RAMP_TORQUE_FRACTION * drive.holding_torque(current) / inertia / drive.step_angle  # [steps/s^2]
    ramp_steps = int(math.ceil((step_rate**2 - rate0**2) / (2.0 * alpha))) if step_rate > rate0 else 0
    k = np.arange(ramp_steps + HOLD_STEPS, dtype=float)
    ramp = (np.sqrt(rate0**2 + 2.0 * alpha * np.minimum(k, ramp_steps)) - rate0) / alpha
    # after the ramp: evenly at step_rate from the ramp's last instant
    t_ramp_end = (np.sqrt(rate0**2 + 2.0 * alpha * ramp_steps) - rate0) / alpha
    times = np.where(k <= ramp_steps, ramp, t_ramp_end + (k - ramp_steps) / step_rate)
    return start + 1.0 / rate0 + times  # the first step one period after the start


def _bench_parameters(drive: MotorDrive, sequencer: Sequencer, load_inertia: float, brake: float) -> dict:
    """The bench's FMU parameters: the drive's motor; the mechanics as inertia, brake and load lever."""
    i_a0, i_b0 = sequencer.reference_currents(0)
    return {
        "motor": {**drive.motor_parameters(), "i_a_start": float(i_a0), "i_b_start": float(i_b0)},
        "mechanics": {
            "J_p": load_inertia * BENCH_RATIO**2,
            "J_m": drive.rotor_inertia,
            "T_c": brake,
            "M_c": 0.0,
            "b": 0.0,
            "r": 0.3 / BENCH_RATIO,
            "s": 0.3,
            "theta_start": float(sequencer.position(0)),
        },
    }


def steps_kept(
    drive: MotorDrive,
    current: float,
    step_rate: float,
    load_torque: float,
    *,
    mode: str = "one-phase-on",
    microsteps: int = 1,
    load_inertia: float = BENCH_LOAD_INERTIA,
    fmus: Mapping[str, Path] | None = None,
    rtol: float = 1e-6,
) -> bool:
    """Whether the motor keeps every step at ``step_rate`` [full steps/s] against a brake of
    ``load_torque`` [N.m] on its shaft; with ``step_rate`` 0, whether it holds its detent under a
    static ``load_torque`` at all (the holding torque's test)."""
    paths = bench_fmus(fmus)
    sequencer = Sequencer(mode=mode, current=current, step_angle=drive.step_angle, microsteps=microsteps)
    inertia = drive.rotor_inertia + load_inertia
    if step_rate > 0:  # a brake: Coulomb friction on the shaft, no static load
        step_times = _ramp_step_times(step_rate * microsteps, drive, current, inertia / microsteps, 0.0)
        brake, levels, load_times = load_torque, np.zeros(1), np.zeros(0)
        stop = float(step_times[-1])
    else:  # a static load through m_ext, raised in LOAD_LEVELS levels; no step
        step_times, brake = np.zeros(0), 0.0
        levels = np.concatenate(([0.0], load_torque * np.arange(1, LOAD_LEVELS + 1) / LOAD_LEVELS * BENCH_RATIO))
        load_times = np.linspace(0.0, LOAD_RAMP_TIME, LOAD_LEVELS + 1)[:-1]
        stop = LOAD_RAMP_TIME + SETTLE_TIME
    indices = np.arange(len(step_times) + 1)
    i_a, i_b = sequencer.reference_currents(indices)
    inputs = [
        PiecewiseConstant("i_a_ref", "motor.i_a_ref", step_times, np.asarray(i_a, dtype=float)),
        PiecewiseConstant("i_b_ref", "motor.i_b_ref", step_times, np.asarray(i_b, dtype=float)),
        PiecewiseConstant("m_ext", "mechanics.m_ext", load_times, levels),
    ]
    parameters = _bench_parameters(drive, sequencer, load_inertia, brake)
    system = CoSimulation(
        {name: read_fmu(path) for name, path in paths.items()}, _DRIVE_CONNECTIONS, inputs, parameters
    )
    if len(step_times) >= 2:  # judged at speed: midway between each of the last JUDGED_STEPS steps
        judged = step_times[-JUDGED_STEPS - 1 :]
        grid = 0.5 * (judged[:-1] + judged[1:])
        commanded = sequencer.position(np.searchsorted(step_times, grid, side="right"))
        stop = float(grid[-1])
    else:  # judged at rest, averaged over the ringing
        grid = np.linspace(stop - 0.5 * SETTLE_TIME, stop, 51)
        commanded = np.full(len(grid), sequencer.position(0))
    # rows every OUTPUT_INTERVAL too: CVODE's step limit counts from one output to the next
    outputs = np.union1d(np.arange(0.0, stop, OUTPUT_INTERVAL), grid)
    try:
        trace = system.simulate(0.0, stop, outputs, SolverOptions(rtol=rtol, max_num_steps=MAX_SOLVER_STEPS)).trace
    except SimulationError:
        # a rotor that slipped under a static load runs away (nothing holds it) and CVODE runs out of
        # steps (MAX_SOLVER_STEPS per output interval): the load is not held
        return False
    rows = trace.drop_duplicates("time", keep="last").set_index("time")
    theta = rows["mechanics.theta"].reindex(grid, method="nearest").to_numpy()
    lag = commanded - theta if len(step_times) >= 2 else np.array([np.mean(commanded - theta)])
    return bool(np.all(np.abs(lag) < 2.0 * drive.step_angle))


def _bisect(kept, upper: float, tolerance: float) -> float:
    """The largest load in [0, upper] that ``kept(load)`` accepts, to ``tolerance`` of ``upper``."""
    low, high = 0.0, upper
    if kept(high):
        return high
    while high - low > tolerance * upper:
        middle = 0.5 * (low + high)
        if kept(middle):
            low = middle
        else:
            high = middle
    return low


def holding_torque(
    drive: MotorDrive, current: float, *, tolerance: float = 0.01, fmus: Mapping[str, Path] | None = None
) -> float:
    """The co-simulated static holding torque [N.m] at ``current`` [A], one phase on: the largest load
    the rotor holds without slipping out of its detent."""
    paths = bench_fmus(fmus)
    upper = 1.2 * drive.holding_torque(current)
    return _bisect(lambda load: steps_kept(drive, current, 0.0, load, fmus=paths), upper, tolerance)


def pull_out_torque(
    drive: MotorDrive,
    current: float,
    step_rate: float,
    *,
    mode: str = "one-phase-on",
    microsteps: int = 1,
    tolerance: float = 0.02,
    load_inertia: float = BENCH_LOAD_INERTIA,
    fmus: Mapping[str, Path] | None = None,
) -> float:
    """The pull-out torque [N.m] at ``step_rate`` [full steps/s]: the largest load torque on the shaft
    against which every step is kept, bisected to ``tolerance`` of the mode's holding torque (two phases
    on: sqrt(2) times one phase's, the peak of the sum of the two phases' torques)."""
    paths = bench_fmus(fmus)
    upper = drive.holding_torque(current) * (math.sqrt(2.0) if mode == "two-phase-on" else 1.0)

    def kept(load: float) -> bool:
        return steps_kept(
            drive, current, step_rate, load, mode=mode, microsteps=microsteps, load_inertia=load_inertia, fmus=paths
        )

    return _bisect(kept, upper, tolerance)


def speed_torque_curve(
    drive: MotorDrive,
    current: float,
    step_rates: Sequence[float],
    *,
    mode: str = "one-phase-on",
    microsteps: int = 1,
    tolerance: float = 0.02,
    load_inertia: float = BENCH_LOAD_INERTIA,
    fmus: Mapping[str, Path] | None = None,
) -> SpeedTorqueCurve:
    """The pull-out torque at each of ``step_rates`` [full steps/s] and the holding torque (co-simulated)."""
    paths = bench_fmus(fmus)
    rates = np.sort(np.asarray(step_rates, dtype=float))
    torques = [
        pull_out_torque(
            drive,
            current,
            rate,
            mode=mode,
            microsteps=microsteps,
            tolerance=tolerance,
            load_inertia=load_inertia,
            fmus=paths,
        )
        for rate in rates
    ]
    held = holding_torque(drive, current, tolerance=tolerance, fmus=paths)
    return SpeedTorqueCurve(current, held, rates, np.asarray(torques), mode, microsteps)
