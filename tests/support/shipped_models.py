"""The models the project ships in models/, built as FMUs by the tests' ``fmu_paths`` fixture."""

MODELS = (
    "StepperMotor",
    "StepperMotorIdealCurrent",
    "PanelMechanics",
    "PanelMechanicsSmallAngle",
    "PanelMechanicsKarnopp",
    "DriveSystem",
    "SunSensor",
)
