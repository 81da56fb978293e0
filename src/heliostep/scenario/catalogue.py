"""The motor catalogue: candidate drives for ``heliostep size``, read and checked before anything runs.

Details: docs/sizing.md, ``heliostep.scenario.catalogue``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from heliostep.errors import InputError
from heliostep.scenario.sections import MAX_PHASE_CURRENT
from heliostep.scenario.yaml_io import read_yaml_file

__all__ = [
    "DEFAULT_CURRENT_GAIN",
    "REQUIRED_KEYS",
    "MotorCandidate",
    "OPTIONAL_KEYS",
    "MotorDrive",
    "close_names",
    "load_catalogue",
    "motor_overrides",
    "role_instance",
    "shipped_catalogue_path",
]

#: Every key an entry needs, with its unit (text keys have none).
REQUIRED_KEYS: dict[str, str] = {
    "manufacturer": "",
    "model": "",
    "datasheet": "",
    "holding_torque": "N.m",
    "rated_current": "A",
    "resistance": "Ohm",
    "inductance": "H",
    "rotor_inertia": "kg.m2",
    "detent_torque": "N.m",
    "step_angle": "deg",
    "bus_voltage": "V",
    "currents": "A",
}

#: Keys an entry may have, with their unit: the frame (e.g. ``NEMA 17``, where the datasheet names it) and the
#: datasheet's test voltage (the supply of its speed-torque curves, where it gives one).
OPTIONAL_KEYS: dict[str, str] = {"frame": "", "test_voltage": "V"}

#: The averaged chopper's loop gain K [V/A] the catalogue's drives run with (the motor FMU's default,
#: docs/physics.md, the driver).
DEFAULT_CURRENT_GAIN = 100.0

_TEXT_KEYS = ("manufacturer", "model", "datasheet", "frame")


@dataclass(frozen=True)
class MotorDrive:
    """A motor and its driver as the motor and mechanics FMUs see them.

    Attributes
    ----------
    resistance : float
        Phase resistance R [Ohm].
    inductance : float
        Phase inductance L [H].
    torque_constant : float
        k_e [N.m/A] of [paper], eqs. 7-9.
    rotor_teeth : float
        N_c [1].
    bus_voltage : float
        The chopper's bus, the FMU's ``V_supply`` [V].
    rotor_inertia : float
        J_m [kg.m2].
    current_gain : float
        The averaged chopper's loop gain K [V/A].
    detent_torque : float or None
        The detent torque amplitude T_d [N.m]; None: the motor FMU's default.
    """

    resistance: float
    inductance: float
    torque_constant: float
    rotor_teeth: float
    bus_voltage: float
    rotor_inertia: float
    current_gain: float = DEFAULT_CURRENT_GAIN
    detent_torque: float | None = None

    @property
    def step_angle(self) -> float:
        """Full-step angle [rad]: pi / (2 N_c)."""
        return math.pi / (2.0 * self.rotor_teeth)

    def held_current(self, current: float) -> float:
        """The current the averaged chopper holds for a reference ``current`` [A]: K I / (K + R)."""
        return self.current_gain * current / (self.current_gain + self.resistance)

    def holding_torque(self, current: float) -> float:
        """Static torque amplitude with one phase at reference ``current`` [N.m]: k_e K I / (K + R)."""
        return self.torque_constant * self.held_current(current)

    def motor_parameters(self) -> dict[str, float]:
        """The motor FMU's parameters (``StepperMotor``'s names)."""
        return {
            "R": self.resistance,
            "L": self.inductance,
            "k_e": self.torque_constant,
            "N_c": self.rotor_teeth,
            "V_supply": self.bus_voltage,
            "K_current": self.current_gain,
            **({} if self.detent_torque is None else {"T_d": self.detent_torque}),
        }


@dataclass(frozen=True)
class MotorCandidate:
    """One catalogue entry: its datasheet values and the currents to try."""

    name: str
    manufacturer: str
    model: str
    datasheet: str
    holding_torque: float  # [N.m] datasheet, two phases on at rated_current
    rated_current: float  # [A]
    resistance: float  # [Ohm]
    inductance: float  # [H]
    rotor_inertia: float  # [kg.m2]
    detent_torque: float  # [N.m]
    step_angle: float  # [deg]
    bus_voltage: float  # [V]
    currents: tuple[float, ...]  # [A]
    frame: str | None = None  # e.g. "NEMA 17", where the datasheet names it
    test_voltage: float | None = None  # [V] the datasheet's speed-torque curves' supply, where it gives one

    @property
    def torque_constant(self) -> float:
        """k_e [N.m/A] = T_hold / (sqrt(2) I_rated) (the datasheet's two phases on)."""
        return self.holding_torque / (math.sqrt(2.0) * self.rated_current)

    def drive(self) -> MotorDrive:
        """The motor FMU's view of this entry."""
        return MotorDrive(
            resistance=self.resistance,
            inductance=self.inductance,
            torque_constant=self.torque_constant,
            rotor_teeth=90.0 / self.step_angle,
            bus_voltage=self.bus_voltage,
            rotor_inertia=self.rotor_inertia,
            detent_torque=self.detent_torque,
        )

    def record(self) -> dict:
        """The entry as the sizing sheet shows it (with the derived k_e)."""
        return {
            "name": self.name,
            "manufacturer": self.manufacturer,
            "model": self.model,
            "datasheet": self.datasheet,
            "holding_torque_Nm": self.holding_torque,
            "rated_current_A": self.rated_current,
            "resistance_Ohm": self.resistance,
            "inductance_H": self.inductance,
            "rotor_inertia_kgm2": self.rotor_inertia,
            "detent_torque_Nm": self.detent_torque,
            "step_angle_deg": self.step_angle,
            "bus_voltage_V": self.bus_voltage,
            "currents_A": list(self.currents),
            "torque_constant_NmA": self.torque_constant,
            "frame": self.frame,
            "test_voltage_V": self.test_voltage,
        }


def shipped_catalogue_path() -> Path:
    """The shipped catalogue, ``heliostep/data/motors.yaml``."""
    return Path(__file__).resolve().parents[1] / "data" / "motors.yaml"


def load_catalogue(path: str | Path | None = None, names: Sequence[str] = ()) -> list[MotorCandidate]:
    """The catalogue's candidates (all, or those named, in the given order), every value checked.

    Raises
    ------
    InputError
        The file cannot be read, has no ``motors`` mapping, an entry misses a key or has a bad value,
        or a name in ``names`` is not in the catalogue: naming the file and the dotted key.
    """
    source = Path(path) if path is not None else shipped_catalogue_path()
    document = read_yaml_file(source, "motor catalogue")
    motors = document.get("motors") if isinstance(document, Mapping) else None
    if not isinstance(motors, Mapping) or not motors:
        raise InputError(f"{source}: motors: expected a mapping of motor name -> datasheet values")
    unknown = [name for name in names if name not in motors]
    if unknown:
        near = list(dict.fromkeys(m for name in unknown for m in close_names(str(name), list(map(str, motors)))))
        hint = f" (close: {', '.join(near)})" if near else ""
        raise InputError(
            f"{source}: unknown motor(s) {', '.join(map(repr, unknown))}{hint}; the catalogue has: {', '.join(motors)}"
        )
    chosen = list(names) if names else list(motors)
    return [_candidate(source, str(name), motors[name]) for name in chosen]


def _candidate(source: Path, name: str, entry) -> MotorCandidate:
    """One entry checked: every key present, numbers positive, currents a non-empty rising list."""
    where = f"{source}: motors.{name}"
    if not isinstance(entry, Mapping):
        raise InputError(f"{where}: expected a mapping of {', '.join(REQUIRED_KEYS)}")
    missing = [key for key in REQUIRED_KEYS if key not in entry or entry[key] is None]
    if missing:
        raise InputError(f"{where}.{missing[0]}: missing (every entry needs {', '.join(REQUIRED_KEYS)})")
    extra = sorted(set(map(str, entry)) - set(REQUIRED_KEYS) - set(OPTIONAL_KEYS))
    if extra:
        expected = f"{', '.join(REQUIRED_KEYS)} (optional: {', '.join(OPTIONAL_KEYS)})"
        raise InputError(f"{where}.{extra[0]}: unknown key; expected {expected}")
    values: dict = {}
    given = {**REQUIRED_KEYS, **{key: unit for key, unit in OPTIONAL_KEYS.items() if entry.get(key) is not None}}
    for key, unit in given.items():
        value = entry[key]
        if key in _TEXT_KEYS:
            if not isinstance(value, str) or not value.strip():
                raise InputError(f"{where}.{key}: expected a non-empty text, got {value!r}")
            values[key] = value
        elif key == "currents":
            values[key] = _currents(f"{where}.{key}", value)
        else:
            values[key] = _positive(f"{where}.{key}", value, unit, allow_zero=key == "detent_torque")
    return MotorCandidate(name=name, **values)


def _positive(where: str, value, unit: str, allow_zero: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InputError(f"{where}: expected a number [{unit}], got {value!r}")
    if value < 0 or (value == 0 and not allow_zero):
        raise InputError(f"{where}: expected {'>= 0' if allow_zero else '> 0'} [{unit}], got {value!r}")
    return float(value)


def _currents(where: str, value) -> tuple[float, ...]:
    if not isinstance(value, list) or not value:
        raise InputError(f"{where}: expected a non-empty list of phase currents [A], got {value!r}")
    currents = tuple(_positive(f"{where}[{k}]", item, "A") for k, item in enumerate(value))
    too_large = [current for current in currents if current > MAX_PHASE_CURRENT]
    if too_large:
        raise InputError(f"{where}: expected phase currents up to {MAX_PHASE_CURRENT:g} A, got {too_large[0]:g}")
    if any(b <= a for a, b in zip(currents, currents[1:])):
        raise InputError(f"{where}: expected rising currents [A], got {list(currents)}")
    return currents


def close_names(name: str, names: Sequence[str], cutoff: float = 0.5) -> list[str]:
    """The names in ``names`` close to ``name`` (a mistyped name's suggestions): those that contain it or that
    it contains, case aside, and those :func:`difflib.get_close_matches` finds at ``cutoff`` (a higher one for
    names that share a long prefix, as the shipped scenarios' ``jan21-``)."""
    import difflib

    low = name.lower()
    contained = [n for n in names if low and (low in n.lower() or n.lower() in low)]
    return list(dict.fromkeys([*contained, *difflib.get_close_matches(name, names, n=5, cutoff=cutoff)]))


def role_instance(scenario, role: str, default: str) -> str:
    """The FMU instance that plays ``role`` in ``scenario`` (``default`` when no role names one)."""
    target = scenario.resolved_roles().get(role)
    return target.partition(".")[0] if target else default


def motor_overrides(scenario, candidate: MotorCandidate) -> tuple[str, ...]:
    """A catalogue entry's drive as ``--set`` items on ``scenario``: the motor FMU's parameters
    (:meth:`MotorDrive.motor_parameters`: R, L, k_e, N_c, V_supply, K_current, T_d) on the instance playing the
    ``torque`` role, the rotor inertia J_m on the one playing ``wind_moment`` (the mechanics) and the
    sequencer's full-step angle. ``heliostep size`` (each case, with its current) and ``heliostep run --motor``
    apply the same items. The current is not set here."""
    motor, mechanics = role_instance(scenario, "torque", "motor"), role_instance(scenario, "wind_moment", "mechanics")
    drive = candidate.drive()
    values = [f"parameters.{motor}.{name}={value!r}" for name, value in drive.motor_parameters().items()]
    return (
        *values,
        f"parameters.{mechanics}.J_m={drive.rotor_inertia!r}",
        f"sequencer.step_angle={candidate.step_angle!r}",
    )
