"""SSP files laid out as other tools write them, for the tests of reading them (tests/fmu/test_ssp_read.py).

The layout is OMSimulator's: the FMUs under ``resources/`` (named by their model, not their instance), a
``SystemStructure.ssd`` whose top system holds nested ``ssd:System`` elements with their own connectors,
units declared in ``ssd:Units``, element geometry and a default experiment, and the parameters in an
``.ssv`` file bound on the top system through an ``.ssm`` mapping, beside inline bindings on a system and on
a component. Everything is written here from text; the FMUs are the project's own (``fmu_paths``).
"""

from __future__ import annotations

import zipfile
from pathlib import Path

HEAD = (
    '<?xml version="1.0" encoding="UTF-8"?>\n'
    '<ssd:SystemStructureDescription xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"'
    ' xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"'
    ' xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"'
    ' xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping"'
    ' version="1.0" name="tracker" generationTool="OMSimulator">\n'
)
SSV = 'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"'
SSM = (
    'xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping"'
    ' xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"'
)


def connector(name: str, kind: str, unit: str | None = None, geometry: bool = True) -> str:
    unit_attribute = f' unit="{unit}"' if unit else ""
    where = '<ssd:ConnectorGeometry x="0.0" y="0.5"/>' if geometry else ""
    return f'<ssd:Connector name="{name}" kind="{kind}"><ssc:Real{unit_attribute}/>{where}</ssd:Connector>'


def connection(start: str, end: str, inner: str = "", extra: str = "") -> str:
    def ends(side: str, text: str) -> str:
        element, dot, name = text.rpartition(".")
        return (f'{side}Element="{element}" ' if dot else "") + f'{side}Connector="{name}"'

    body = f">{inner}</ssd:Connection>" if inner else "/>"
    return f"<ssd:Connection {ends('start', start)} {ends('end', end)}{extra}{body}"


GEOMETRY = '<ssd:ElementGeometry x1="10.0" y1="-10.0" x2="30.0" y2="10.0" rotation="0.0"/>'


def component(name: str, model: str, connectors: list[tuple[str, str, str]], binding: str = "") -> str:
    """An FMU component (``resources/MODEL.fmu``) with its connectors (name, kind, unit) and binding."""
    return (
        f'<ssd:Component name="{name}" type="application/x-fmu-sharedlibrary" source="resources/{model}.fmu">'
        f"<ssd:Connectors>{''.join(connector(*c) for c in connectors)}</ssd:Connectors>"
        f"{GEOMETRY}{binding}</ssd:Component>"
    )


def nested_ssd(motor_binding: str = "", tau_transform: str = "", load_tau_unit: str = "N.cm") -> str:
    """The drive as OMSimulator nests it: top system ``Root`` > system ``drive`` (the motor) > system ``load``
    (the panel mechanics), the torque through ``load``'s connector ``tau`` (in N.cm) and the angle and speed
    out through its ``theta`` and ``omega``; ``load``'s parameter connector ``friction`` feeds the
    mechanics' ``T_c``."""
    motor = component(
        "motor",
        "StepperMotor",
        [("i_a_ref", "input", "A"), ("i_b_ref", "input", "A"), ("theta", "input", "rad"), ("omega", "input", "rad/s")]
        + [("tau", "output", "N.m"), ("R", "parameter", "Ohm")],
        motor_binding,
    )
    mechanics = component(
        "mechanics",
        "PanelMechanics",
        [
            ("tau", "input", "N.m"),
            ("theta", "output", "rad"),
            ("omega", "output", "rad/s"),
            ("T_c", "parameter", "N.m"),
        ],
    )
    load = (
        '<ssd:System name="load"><ssd:Connectors>'
        + connector("tau", "input", load_tau_unit)
        + connector("theta", "output")
        + connector("omega", "output")
        + connector("friction", "parameter", "N.m")
        + "</ssd:Connectors>"
        + GEOMETRY
        + "<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>"
        + f'<ssv:ParameterSet {SSV} version="1.0" name="load"><ssv:Parameters>'
        + '<ssv:Parameter name="friction"><ssv:Real value="0.1" unit="N.m"/></ssv:Parameter>'
        + "</ssv:Parameters></ssv:ParameterSet>"
        + "</ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>"
        + f"<ssd:Elements>{mechanics}</ssd:Elements><ssd:Connections>"
        + connection("tau", "mechanics.tau")
        + connection("mechanics.theta", "theta")
        + connection("mechanics.omega", "omega")
        + connection("friction", "mechanics.T_c")
        + "</ssd:Connections></ssd:System>"
    )
    drive = (
        '<ssd:System name="drive">'
        + GEOMETRY
        + '<ssd:ParameterBindings><ssd:ParameterBinding prefix="load.mechanics."><ssd:ParameterValues>'
        + f'<ssv:ParameterSet {SSV} version="1.0" name="bearings"><ssv:Parameters>'
        + '<ssv:Parameter name="M_c"><ssv:Real value="0.004"/></ssv:Parameter>'
        + "</ssv:Parameters></ssv:ParameterSet>"
        + "</ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>"
        + f"<ssd:Elements>{motor}{load}</ssd:Elements><ssd:Connections>"
        + connection("motor.tau", "load.tau", tau_transform)
        + connection("load.theta", "motor.theta")
        + connection("load.omega", "motor.omega")
        + "</ssd:Connections></ssd:System>"
    )
    return (
        HEAD
        + '<ssd:System name="Root"><ssd:ParameterBindings>'
        + '<ssd:ParameterBinding source="resources/tracker.ssv">'
        + '<ssd:ParameterMapping source="resources/tracker.ssm"/></ssd:ParameterBinding>'
        + f"</ssd:ParameterBindings><ssd:Elements>{drive}</ssd:Elements>"
        + '<ssd:Annotations><ssc:Annotation type="org.openmodelica">'
        + '<oms:Annotations xmlns:oms="https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms">'
        + '<oms:SimulationInformation><oms:FixedStepMaster description="oms-ma" stepSize="1e-3"/>'
        + "</oms:SimulationInformation></oms:Annotations></ssc:Annotation></ssd:Annotations>"
        + "</ssd:System>"
        + '<ssd:Units><ssc:Unit name="N.cm"><ssc:BaseUnit kg="1" m="2" s="-2" factor="0.01"/></ssc:Unit></ssd:Units>'
        + '<ssd:DefaultExperiment startTime="0.0" stopTime="60.0"/>'
        + "</ssd:SystemStructureDescription>\n"
    )


#: The top system's parameter set: the winding resistance in milliohm, the panel's inertia at half
#: (the mapping doubles it), a name the system does not have (ignored, as SSP 1.0 says).
TRACKER_SSV = (
    f'<?xml version="1.0" encoding="UTF-8"?>\n<ssv:ParameterSet {SSV}'
    ' xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" version="1.0" name="tracker">'
    "<ssv:Parameters>"
    '<ssv:Parameter name="winding_resistance"><ssv:Real value="1500" unit="mOhm"/></ssv:Parameter>'
    '<ssv:Parameter name="half_inertia"><ssv:Real value="2.0"/></ssv:Parameter>'
    '<ssv:Parameter name="drive.nothing.here"><ssv:Real value="1.0"/></ssv:Parameter>'
    "</ssv:Parameters><ssv:Units>"
    '<ssc:Unit name="mOhm"><ssc:BaseUnit kg="1" m="2" s="-3" A="-2" factor="0.001"/></ssc:Unit>'
    "</ssv:Units></ssv:ParameterSet>\n"
)
TRACKER_SSM = (
    f'<?xml version="1.0" encoding="UTF-8"?>\n<ssm:ParameterMapping {SSM} version="1.0">'
    '<ssm:MappingEntry source="winding_resistance" target="drive.motor.R"/>'
    '<ssm:MappingEntry source="half_inertia" target="drive.load.mechanics.J_p">'
    '<ssc:LinearTransformation factor="2.0"/></ssm:MappingEntry>'
    "</ssm:ParameterMapping>\n"
)
#: The motor's own binding: R (which the top system's binding overrides) and T_d.
MOTOR_BINDING = (
    "<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>"
    f'<ssv:ParameterSet {SSV} version="1.0" name="motor"><ssv:Parameters>'
    '<ssv:Parameter name="R"><ssv:Real value="0.5"/></ssv:Parameter>'
    '<ssv:Parameter name="T_d"><ssv:Real value="0.05"/></ssv:Parameter>'
    "</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>"
)
#: What the flattened system is: instances, connections (in the order the file's connections reach the
#: inputs), parameters.
FLAT_INSTANCES = {"drive_motor": "StepperMotor", "drive_load_mechanics": "PanelMechanics"}
FLAT_CONNECTIONS = [
    ("drive_load_mechanics.theta", "drive_motor.theta"),
    ("drive_load_mechanics.omega", "drive_motor.omega"),
    ("drive_motor.tau", "drive_load_mechanics.tau"),
]
FLAT_PARAMETERS = {
    "drive_motor": {"R": 1.5, "T_d": 0.05},
    "drive_load_mechanics": {"J_p": 4.0, "M_c": 0.004, "T_c": 0.1},
}


def write_ssp(out: Path, ssd: str, fmus: dict[str, Path], extra: dict[str, str] | None = None) -> Path:
    """An .ssp of ``ssd``, the FMUs (member name -> file) and ``extra`` members (name -> text)."""
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("SystemStructure.ssd", ssd)
        for member, path in fmus.items():
            archive.write(path, member)
        for member, text in (extra or {}).items():
            archive.writestr(member, text)
    return out


def tracker_ssp(out: Path, fmu_paths, **ssd) -> Path:
    """The nested drive of :func:`nested_ssd` with its parameter files, as an .ssp at ``out``."""
    return write_ssp(
        out,
        nested_ssd(motor_binding=MOTOR_BINDING, **ssd),
        {f"resources/{name}.fmu": fmu_paths[name] for name in ("StepperMotor", "PanelMechanics")},
        {"resources/tracker.ssv": TRACKER_SSV, "resources/tracker.ssm": TRACKER_SSM},
    )
