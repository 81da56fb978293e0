"""``modelDescription.xml`` of an exported model (FMI 2.0 or 3.0 Model Exchange), and the value
references of its variables (:class:`Layout`, shared with the C header :mod:`heliostep.fmu.export`
writes).

Causality, variability, initial, start values, units (with their SI base units), descriptions and
a ``ModelStructure`` whose dependencies come from CasADi's Jacobian sparsity of the model's
evaluation function, so an importer knows the direct feedthrough exactly.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import TYPE_CHECKING

from heliostep.fmu.modelica import FlatModel, ModelicaError, Variable

if TYPE_CHECKING:  # (annotations only: casadi is imported where an FMU is built)
    import casadi as ca

__all__ = ["BASE_UNITS", "Layout", "build_description_fmi3", "model_description", "model_description_fmi3"]

#: Exponents of the SI base units of the units the models use (FMI 2.0 ``BaseUnit``).
BASE_UNITS = {
    "1": {},
    "s": {"s": 1},
    "m": {"m": 1},
    "rad": {"rad": 1},
    "rad/s": {"rad": 1, "s": -1},
    "A": {"A": 1},
    "V": {"kg": 1, "m": 2, "s": -3, "A": -1},
    "W": {"kg": 1, "m": 2, "s": -3},
    "J": {"kg": 1, "m": 2, "s": -2},
    "H": {"kg": 1, "m": 2, "s": -2, "A": -2},
    "Ohm": {"kg": 1, "m": 2, "s": -3, "A": -2},
    "V/A": {"kg": 1, "m": 2, "s": -3, "A": -2},
    "N.m": {"kg": 1, "m": 2, "s": -2},
    "N.m/A": {"kg": 1, "m": 2, "s": -2, "A": -1},
    "N.m.s/rad": {"kg": 1, "m": 2, "s": -1, "rad": -1},
    "kg": {"kg": 1},
    "kg.m2": {"kg": 1, "m": 2},
}


@dataclass(frozen=True)
class Layout:
    """Value references of the flat model's variables: the index into the C layer's r[]."""

    variables: list[Variable]

    @classmethod
    def of(cls, model: FlatModel) -> Layout:
        return cls(
            model.parameters
            + model.states
            + model.inputs
            + model.derivatives
            + model.algebraics
            + model.calculated_parameters
        )

    def vr(self, name: str) -> int:
        return next(i for i, v in enumerate(self.variables) if v.name == name)


def _dependencies(evaluate: ca.Function, model: FlatModel, layout: Layout) -> dict[str, list[int]]:
    """For every computed variable, the 1-based indices of the states and inputs it depends on."""
    computed = model.derivatives + model.algebraics + model.calculated_parameters
    knowns = [(1, model.states), (2, model.inputs)]
    deps: dict[str, list[int]] = {v.name: [] for v in computed}
    for input_index, variables in knowns:
        if not variables:
            continue
        sparsity = evaluate.sparsity_jac(input_index, 0)
        columns = sparsity.get_col()
        for k, row in enumerate(sparsity.row()):
            deps[computed[row].name].append(layout.vr(variables[columns[k]].name) + 1)
    return {name: sorted(set(indices)) for name, indices in deps.items()}


def model_description(
    model: FlatModel,
    layout: Layout,
    guid: str,
    evaluate: ca.Function,
    generation_tool: str,
    source_files: tuple[str, ...],
) -> bytes:
    """``modelDescription.xml`` for the model (FMI 2.0, Model Exchange only); ``source_files``
    are the C files the FMU's ``sources/`` folder holds."""
    root = ET.Element(
        "fmiModelDescription",
        {
            "fmiVersion": "2.0",
            "modelName": model.name,
            "guid": guid,
            "description": model.description,
            "generationTool": generation_tool,
            "variableNamingConvention": "structured",
            "numberOfEventIndicators": "0",
        },
    )
    me = ET.SubElement(
        root,
        "ModelExchange",
        {
            "modelIdentifier": model.name,
            "canGetAndSetFMUstate": "false",
            "canSerializeFMUstate": "false",
            "providesDirectionalDerivative": "false",
            "canNotUseMemoryManagementFunctions": "false",
            "completedIntegratorStepNotNeeded": "true",
        },
    )
    listed = ET.SubElement(me, "SourceFiles")
    for name in source_files:
        ET.SubElement(listed, "File", {"name": name})
    _unit_definitions(root, layout)
    categories = ET.SubElement(root, "LogCategories")
    for name, text in (("logStatusError", "errors"), ("logStatusFatal", "fatal errors"), ("logAll", "all messages")):
        ET.SubElement(categories, "Category", {"name": name, "description": text})
    ET.SubElement(root, "DefaultExperiment", {"startTime": "0", "stopTime": "1", "tolerance": "1e-06"})
    variables = ET.SubElement(root, "ModelVariables")
    state_index = {v.name: layout.vr(v.name) + 1 for v in model.states}
    for vr, v in enumerate(layout.variables):
        attributes, real = _scalar_variable(v, vr, state_index)
        element = ET.SubElement(variables, "ScalarVariable", attributes)
        ET.SubElement(element, "Real", real)
    _model_structure(root, model, layout, _dependencies(evaluate, model, layout))
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"


def _unit_definitions(root: ET.Element, layout: Layout, extra: tuple[str, ...] = ()) -> None:
    """``UnitDefinitions``: every unit the variables use (and ``extra``), with its SI base units where known."""
    units = sorted({v.unit for v in layout.variables if v.unit} | set(extra))
    if units:
        unit_definitions = ET.SubElement(root, "UnitDefinitions")
        for unit in units:
            element = ET.SubElement(unit_definitions, "Unit", {"name": unit})
            if unit in BASE_UNITS:
                ET.SubElement(element, "BaseUnit", {k: str(e) for k, e in BASE_UNITS[unit].items()})


def _scalar_variable(v: Variable, vr: int, state_index: dict[str, int]) -> tuple[dict[str, str], dict[str, str]]:
    """The attributes of variable ``v``'s ``ScalarVariable`` (value reference ``vr``) and of its ``Real``."""
    attributes = {"name": v.name, "valueReference": str(vr)}
    if v.description:
        attributes["description"] = v.description
    real: dict[str, str] = {}
    if v.kind == "parameter":
        attributes.update(causality="parameter", variability="tunable", initial="exact")
        real["start"] = repr(v.start)
    elif v.kind == "calculated_parameter":
        attributes.update(causality="calculatedParameter", variability="tunable", initial="calculated")
    elif v.kind == "input":
        attributes.update(causality="input", variability="continuous")
        real["start"] = repr(v.start or 0.0)
    else:
        attributes.update(causality="output" if v.is_output else "local", variability="continuous")
        if v.kind == "state" and v.start is not None:
            attributes["initial"] = "exact"
            real["start"] = repr(v.start)
        else:
            attributes["initial"] = "calculated"
    if v.kind == "derivative":
        if v.state_name is None:
            raise ModelicaError(f"{v.name}: a derivative without its state")
        real["derivative"] = str(state_index[v.state_name])
    if v.unit:
        real["unit"] = v.unit
    if v.kind == "state" and v.nominal:
        real["nominal"] = repr(v.nominal)
    for bound in ("min", "max"):
        value = getattr(v, bound)
        if value is not None:
            real[bound] = repr(value)
    return attributes, real


def _model_structure(root: ET.Element, model: FlatModel, layout: Layout, deps: dict[str, list[int]]) -> None:
    """``ModelStructure``: outputs and derivatives with their dependencies, the initial unknowns; a list
    with nothing in it is left out (FMI 2.0's schema wants at least one ``Unknown`` in each, so a model
    without states has no ``Derivatives``)."""
    structure = ET.SubElement(root, "ModelStructure")
    outputs = []
    for v in layout.variables:
        if v.is_output:
            index = layout.vr(v.name) + 1
            dependencies = [index] if v.kind == "state" else deps[v.name]
            outputs.append({"index": str(index), "dependencies": " ".join(map(str, dependencies))})
    derivatives = [
        {"index": str(layout.vr(v.name) + 1), "dependencies": " ".join(map(str, deps[v.name]))}
        for v in model.derivatives
    ]
    initial = [
        {"index": str(vr + 1)}
        for vr, v in enumerate(layout.variables)
        if (v.is_output and not (v.kind == "state" and v.start is not None))
        or v.kind in ("derivative", "calculated_parameter")
        or (v.kind == "state" and v.start is None)
    ]
    for name, unknowns in (("Outputs", outputs), ("Derivatives", derivatives), ("InitialUnknowns", initial)):
        if unknowns:
            element = ET.SubElement(structure, name)
            for attributes in unknowns:
                ET.SubElement(element, "Unknown", attributes)


# ---------------------------------------------------------------- FMI 3.0


def model_description_fmi3(
    model: FlatModel,
    layout: Layout,
    instantiation_token: str,
    evaluate: ca.Function,
    generation_tool: str,
    source_files: tuple[str, ...],
) -> bytes:
    """``modelDescription.xml`` for the model in FMI 3.0 form (Model Exchange only): the same
    variables, value references, units and dependencies as :func:`model_description`, as
    ``Float64`` variables, plus the independent variable ``time`` (value reference
    ``len(layout.variables)``); the ``ModelStructure`` lists value references (FMI 3.0),
    not 1-based indices. ``source_files`` go to ``sources/buildDescription.xml``
    (:func:`build_description_fmi3`), which FMI 3.0 uses instead of ``SourceFiles``."""
    del source_files  # listed in buildDescription.xml
    root = ET.Element(
        "fmiModelDescription",
        {
            "fmiVersion": "3.0",
            "modelName": model.name,
            "instantiationToken": instantiation_token,
            "description": model.description,
            "generationTool": generation_tool,
            "variableNamingConvention": "structured",
        },
    )
    ET.SubElement(
        root,
        "ModelExchange",
        {
            "modelIdentifier": model.name,
            "needsCompletedIntegratorStep": "false",
            "canGetAndSetFMUState": "false",
            "canSerializeFMUState": "false",
            "providesDirectionalDerivatives": "false",
            "providesAdjointDerivatives": "false",
        },
    )
    _unit_definitions(root, layout, ("s",))  # "s": the unit of time
    categories = ET.SubElement(root, "LogCategories")
    for name, text in (("logStatusError", "errors"), ("logStatusFatal", "fatal errors"), ("logAll", "all messages")):
        ET.SubElement(categories, "Category", {"name": name, "description": text})
    ET.SubElement(root, "DefaultExperiment", {"startTime": "0", "stopTime": "1", "tolerance": "1e-06"})
    variables = ET.SubElement(root, "ModelVariables")
    time_attributes = {"name": "time", "valueReference": str(len(layout.variables)), "causality": "independent"}
    ET.SubElement(variables, "Float64", {**time_attributes, "variability": "continuous", "unit": "s"})
    state_vr = {v.name: layout.vr(v.name) + 1 for v in model.states}
    for vr, v in enumerate(layout.variables):
        attributes, real = _scalar_variable(v, vr, state_vr)
        if "derivative" in real:  # FMI 3.0: the state's value reference, FMI 2.0: its 1-based index
            real["derivative"] = str(int(real["derivative"]) - 1)
        ET.SubElement(variables, "Float64", {**attributes, **real})
    deps = {name: [i - 1 for i in indices] for name, indices in _dependencies(evaluate, model, layout).items()}
    _model_structure_fmi3(root, model, layout, deps)
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"


def _model_structure_fmi3(root: ET.Element, model: FlatModel, layout: Layout, deps: dict[str, list[int]]) -> None:
    """FMI 3.0 ``ModelStructure``: ``Output``, ``ContinuousStateDerivative`` and ``InitialUnknown``
    elements, in this order, each naming its variable and its dependencies by value reference."""
    structure = ET.SubElement(root, "ModelStructure")

    def unknown(tag: str, vr: int, dependencies: list[int] | None) -> None:
        attributes = {"valueReference": str(vr)}
        if dependencies is not None:
            attributes["dependencies"] = " ".join(map(str, dependencies))
        ET.SubElement(structure, tag, attributes)

    for v in layout.variables:
        if v.is_output:
            vr = layout.vr(v.name)
            unknown("Output", vr, [vr] if v.kind == "state" else deps[v.name])
    for v in model.derivatives:
        unknown("ContinuousStateDerivative", layout.vr(v.name), deps[v.name])
    for vr, v in enumerate(layout.variables):
        if (
            (v.is_output and not (v.kind == "state" and v.start is not None))
            or v.kind in ("derivative", "calculated_parameter")
            or (v.kind == "state" and v.start is None)
        ):
            unknown("InitialUnknown", vr, None)


def build_description_fmi3(model_identifier: str, source_files: tuple[str, ...]) -> bytes:
    """``sources/buildDescription.xml`` (FMI 3.0 standard): the C files to compile."""
    root = ET.Element("fmiBuildDescription", {"fmiVersion": "3.0"})
    configuration = ET.SubElement(root, "BuildConfiguration", {"modelIdentifier": model_identifier})
    file_set = ET.SubElement(configuration, "SourceFileSet", {"language": "C99"})
    for name in source_files:
        ET.SubElement(file_set, "SourceFile", {"name": name})
    ET.SubElement(file_set, "IncludeDirectory", {"name": "."})
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"
