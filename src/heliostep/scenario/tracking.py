"""The scenario's ``tracking`` section (open loop, closed loop on a sun sensor, or hybrid) and its ``faults``."""

from __future__ import annotations

from typing import Literal, get_args

from pydantic import Field, field_validator, model_validator

from heliostep.scenario.keys import KeyProblems
from heliostep.scenario.sections import Real, Section
from heliostep.scenario.sun_sensors import sun_sensor

__all__ = ["TRACKING_MODES", "CloudConfig", "FaultsConfig", "TrackingConfig"]

#: How the drive is told where to go: the astronomical reference alone, the sun sensor alone, or both.
TrackingMode = Literal["open_loop", "closed_loop", "hybrid"]
TRACKING_MODES = get_args(TrackingMode)


class CloudConfig(Section):
    """``tracking.clouds[]``: a cloud over the sun from ``start`` to ``end`` [s from the window's start],
    the direct irradiance times ``dni_fraction`` meanwhile."""

    start: Real = Field(ge=0.0, description="[s] from the window's start")
    end: Real = Field(gt=0.0, description="[s] from the window's start")
    dni_fraction: Real = Field(0.0, ge=0.0, le=1.0, description="[-] of the direct irradiance left")

    @model_validator(mode="after")
    def _ordered(self) -> CloudConfig:
        if not self.end > self.start:
            raise KeyProblems([(("end",), f"expected after start ({self.start:g} s), got {self.end:g} s")])
        return self


class TrackingConfig(Section):
    """``tracking``: open loop (the default: steps from the sun's computed position), closed loop on the sun
    sensor's signal, or hybrid (the computed position, corrected by the sensor while the sun is bright)."""

    mode: TrackingMode = Field("open_loop", description="open_loop, closed_loop or hybrid")
    sensor: str = Field("ssoc-d60", description="a preset of heliostep/data/sun_sensors.yaml")
    sample_period: Real = Field(10.0, gt=0.0, description="[s] between two readings of the sensor")
    dead_band: Real | None = Field(
        None, ge=0.0, description="[deg] of panel angle left alone; null: the sensor's accuracy on the panel"
    )
    step_rate: Real = Field(50.0, gt=0.0, description="[steps/s] of the moves the controller commands")
    latency: Real = Field(0.01, ge=0.0, description="[s] from a reading to the first step it commands")
    move: Real | None = Field(
        None, gt=0.0, description="[deg] of panel angle per reading (seed 001's delta beta); null: what the sensor asks"
    )
    noise_std: Real | None = Field(
        None, ge=0.0, description="[deg] of the sensor's angle, a reading's random error; null: the preset's"
    )
    seed: int = Field(0, ge=0, description="of the readings' noise")
    clouds: list[CloudConfig] = Field(default_factory=list, description="spans with less direct irradiance")

    @property
    def cloud_spans(self) -> list[tuple[float, float, float]]:
        """The clouds as (start [s], end [s], DNI fraction [-])."""
        return [(c.start, c.end, c.dni_fraction) for c in self.clouds]

    @field_validator("sensor")
    @classmethod
    def _a_preset(cls, name: str) -> str:
        sun_sensor(name)  # an InputError naming the presets: a value error of this key
        return name

    @model_validator(mode="after")
    def _fits_a_sample(self) -> TrackingConfig:
        if self.latency >= self.sample_period:
            raise KeyProblems(
                [(("latency",), f"expected less than sample_period ({self.sample_period:g} s), got {self.latency:g} s")]
            )
        return self


class FaultsConfig(Section):
    """``faults``: what goes wrong in any tracking mode."""

    clock_offset: Real = Field(0.0, description="[s] the controller's clock ahead of true time (behind: < 0)")
    mounting_offset: Real = Field(0.0, description="[deg] the sun sensor's mounting error on the panel")
    stuck: tuple[Real, Real] | None = Field(
        None, description="[start, end] [s from the window's start]: the driver ignores the steps meanwhile"
    )

    @model_validator(mode="after")
    def _stuck_ordered(self) -> FaultsConfig:
        if self.stuck is not None and not 0.0 <= self.stuck[0] < self.stuck[1]:
            raise KeyProblems(
                [(("stuck",), f"expected [start, end] with 0 <= start < end [s], got {list(self.stuck)}")]
            )
        return self


#: The sun sensor's instance a closed or hybrid loop adds to ``fmus`` (unless named there) and its model.
SENSOR_INSTANCE, SENSOR_MODEL = "sensor", "SunSensor"


def with_sensor(data: dict) -> dict:
    """A scenario's mapping with the sun sensor's instance in ``fmus`` when its tracking needs one."""
    tracking = data.get("tracking")
    mode = tracking.get("mode") if isinstance(tracking, dict) else None
    if mode in ("closed_loop", "hybrid"):
        fmus = data.get("fmus")
        fmus = dict(fmus) if isinstance(fmus, dict) else {}
        fmus.setdefault(SENSOR_INSTANCE, SENSOR_MODEL)
        data = {**data, "fmus": fmus}
    return data


def with_sensor_connection(pairs, tracking: TrackingConfig, panel_angle: str | None) -> list:
    """Connections ``pairs`` with the panel's angle (its role's output) to the sun sensor, where a closed or
    hybrid loop has one and nothing connects it yet."""
    sensor = f"{SENSOR_INSTANCE}.theta_p"
    if tracking.mode == "open_loop" or any(target == sensor for _, target in pairs):
        return list(pairs)
    return [*pairs, (panel_angle or "mechanics.theta_p", sensor)]
