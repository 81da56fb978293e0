"""The stepper drive's commands: phase patterns, the step schedule, scenario -> drive inputs.

:mod:`~heliostep.drive.sequencer` (phase patterns, step instants as exact roots of the
reference) and :mod:`~heliostep.drive.inputs` (from a scenario: the reference from the sun,
the schedule, the reference currents, the output grid). Imports :mod:`heliostep.scenario` and
:mod:`heliostep.solar`; never :mod:`heliostep.cosim` (the run hands the drive's arrays to the
master).
"""
