"""heliostep: co-simulation of the stepper drives of solar-tracking mirrors."""

__version__ = "0.1.0"
