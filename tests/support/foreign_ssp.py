"""SSP 1.0 files written by another tool, pyssp-standard (PyPI, MIT), and run by heliostep and by libcosim.

The system is the two-mass oscillator of ``two_oscillators`` (two mini Oscillator FMUs, FMI 2.0 Co-Simulation),
written twice with pyssp-standard's SSD, SSV and SSM writers and its SSP archive:

- :func:`write_flat`, within what libcosim's SSP loader reads: one system of two components, connector units,
  ``a``'s parameters in ``resources/a.ssv``, ``b``'s inline, the force ``b.F_c -> a.F`` through a linear
  transformation, a default experiment with OSP's fixed-step annotation (and no ``ssd:Units``: pyssp-standard
  writes them after the experiment, against SSP 1.0's schema);
- :func:`write_nested`, what libcosim does not read: ``a`` in system ``left``, ``b`` in system ``right``, the
  connections through the systems' connectors (``left.x`` in cm: m -> cm -> m on the way to ``b.x_in``), the
  parameters in ``resources/oscillators.ssv`` bound on the top system through ``resources/oscillators.ssm``
  (a mass in grams mapped onto ``left.a.m`` by factor 0.001), an inline set with a prefix on ``right``, a
  component binding the top's overrides, the units' definitions (pint's, through pyssp-standard) in ``ssd:Units``.

Both give :data:`two_oscillators.PARAMETERS`. pyssp-standard 0.9.1 writes a connection without the
transformation it holds (its ``Connection.as_element`` leaves it out): :class:`TransformedConnection`
appends the element pyssp-standard's own ``Transformation`` writes.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from two_oscillators import CONNECTIONS

#: the force's transformation on ``b.F_c -> a.F`` (factor, offset)
FORCE = (0.5, 0.02)
#: the flat file's outputs compared, and the nested file's names of them
OUTPUTS = ("a.x", "a.v", "b.x", "b.v", "b.F_c")
NESTED = {"a": "left_a", "b": "right_b"}
#: the mass of ``a`` in grams in the nested file's .ssv, mapped by this factor onto ``left.a.m`` [kg]
GRAMS, TO_KG = 1000.0, 0.001
_UNITS = {"x": "m", "x_in": "m", "v": "m/s", "v_in": "m/s", "F": "N", "F_c": "N"}
#: the parameters' units (pyssp-standard 0.9.1 writes no Real value without one)
PARAMETER_UNITS = {
    "m": "kg",
    "c": "N/m",
    "d": "N.s/m",
    "x0": "m",
    "c_c": "N/m",
    "d_c": "N.s/m",
    "mass_a_g": "g",
    "stiffness_b": "N/m",
}
_KINDS = {"F": "input", "x_in": "input", "v_in": "input", "x": "output", "v": "output", "F_c": "output"}


def _pyssp():
    import pyssp_standard.ssd as ssd

    class TransformedConnection(ssd.Connection):
        """pyssp-standard's Connection, written with its transformation."""

        def as_element(self):
            element = super().as_element()
            if self.transformation is not None:
                element.append(self.transformation.element())
            return element

    return ssd, TransformedConnection


def _connectors(ssd, names, units: dict[str, str]):
    from pyssp_standard.common_content_ssc import TypeReal

    return [ssd.Connector(name=n, kind=_KINDS.get(n, "parameter"), type_=TypeReal(units.get(n))) for n in names]


def _component(ssd, name: str, fmu: str, names, binding=None):
    component = ssd.Component()
    component.name, component.component_type, component.source = name, "application/x-fmu-sharedlibrary", fmu
    component.connectors = _connectors(ssd, names, _UNITS)
    component.parameter_bindings = [binding] if binding is not None else None
    return component


def _inline(ssd, values: dict[str, float], name: str, prefix: str | None = None):
    from pyssp_standard.parameter_types import ParameterType
    from pyssp_standard.ssv import SSVElem

    parameters = [
        {"name": k, "type_name": "Real", "type_value": ParameterType("Real", {"value": repr(v), "unit": _unit(k)})}
        for k, v in values.items()
    ]
    return ssd.ParameterBinding(prefix=prefix, ssv=SSVElem(name=name, parameters=parameters))


def _unit(parameter: str) -> str:
    return PARAMETER_UNITS[parameter.rpartition(".")[2]]


def _parameter_file(archive, name: str, values: dict[str, float]) -> str:
    from pyssp_standard.ssv import SSV

    path = archive.unpacked_path / "resources" / name
    path.parent.mkdir(exist_ok=True)
    with SSV(path, mode="w") as ssv:
        ssv.name, ssv.version = Path(name).stem, "1.0"
        for parameter, value in values.items():
            ssv.add_parameter(parameter, "Real", value=repr(value), unit=_unit(parameter))
    return f"resources/{name}"


@functools.cache
def _base_unit(name: str) -> dict:
    """pyssp-standard's definition of unit ``name`` (from pint; a new registry each call, so kept)."""
    from pyssp_standard.unit_conversion import generate_base_unit

    return generate_base_unit(name)


def _units(ssd_file) -> None:
    """The units that differ across a connection (m, cm) in ``ssd:Units``."""
    from pyssp_standard.unit import BaseUnit, Unit

    for name in ("m", "cm"):
        ssd_file.units.add_unit(Unit(name, base_unit=BaseUnit(_base_unit(name))))


def _experiment(ssd, stop: float, step: float):
    from lxml import etree
    from pyssp_standard.common_content_ssc import Annotation

    experiment = ssd.DefaultExperiment()
    experiment.start_time, experiment.stop_time = 0.0, stop
    osp, ssc = "http://opensimulationplatform.com/SSP/OSPAnnotations", ssd.Connection.namespaces["ssc"]
    # the osp namespace declared on the annotation: libcosim reads an attribute of osp:Algorithm as an algorithm
    annotation = Annotation(
        etree.Element(f"{{{ssc}}}Annotation", type="com.opensimulationplatform", nsmap={"osp": osp})
    )
    algorithm = etree.SubElement(annotation.root, f"{{{osp}}}Algorithm")
    etree.SubElement(algorithm, f"{{{osp}}}FixedStepAlgorithm", baseStepSize=repr(step))
    experiment.annotations.add_annotation(annotation)
    return experiment


def _write(out: Path, fmus: dict[str, Path], build) -> Path:
    """The archive ``out``: ``fmus`` under ``resources/``, the SSD ``build(ssd module, archive, ssd file)`` fills."""
    from pyssp_standard import SSP

    out.unlink(missing_ok=True)
    with SSP(out, mode="w") as archive:
        for fmu in fmus.values():
            archive.add_resource(fmu)
        with archive.system_structure as ssd_file:
            ssd_file.name, ssd_file.version = out.stem, "1.0"
            build(archive, ssd_file)
    return out


def write_flat(
    out: Path,
    fmus: dict[str, Path],
    parameters: dict[str, dict[str, float]],
    units: bool = False,
    change=None,
    connections=CONNECTIONS,
) -> Path:
    """The flat file (libcosim's subset): components ``a`` and ``b``, ``connections`` (output, input), the one
    into ``a.F`` transformed by :data:`FORCE`, a default experiment; with ``units``, ``ssd:Units`` too, which
    pyssp-standard writes after the experiment (SSP 1.0's schema has them before it); ``change(pyssp_standard.ssd,
    system)`` changes the system before it is written."""
    ssd, connection = _pyssp()
    ports = {name: [end.split(".")[1] for pair in connections for end in pair if end[0] == name] for name in "ab"}

    def build(archive, ssd_file) -> None:
        system = ssd.System(name="oscillators")
        a_set = ssd.ParameterBinding(source=_parameter_file(archive, "a.ssv", parameters["a"]))
        system.elements = [
            _component(ssd, "a", f"resources/{fmus['a'].name}", [*ports["a"], *parameters["a"]], a_set),
            _component(ssd, "b", f"resources/{fmus['b'].name}", [*ports["b"], *parameters["b"]]),
        ]
        system.elements[1].parameter_bindings = [_inline(ssd, parameters["b"], "b")]
        for source, target in connections:
            (s, sc), (t, tc) = source.split("."), target.split(".")
            link = connection(start_element=s, start_connector=sc, end_element=t, end_connector=tc)
            if target == "a.F":
                link.transformation = _linear(*FORCE)
            system.connections.append(link)
        if change is not None:
            change(ssd, system)
        ssd_file.system = system
        ssd_file.default_experiment = _experiment(ssd, 1.0, 1e-3)
        if units:
            _units(ssd_file)

    return _write(out, fmus, build)


def _linear(factor: float, offset: float):
    from pyssp_standard.transformation_types import Transformation

    return Transformation("LinearTransformation", {"factor": factor, "offset": offset})


def _system_connectors(ssd, ports: dict[str, tuple[str, str]]):
    from pyssp_standard.common_content_ssc import TypeReal

    return [ssd.Connector(name=n, kind=kind, type_=TypeReal(unit)) for n, (kind, unit) in ports.items()]


def write_nested(out: Path, fmus: dict[str, Path], parameters: dict[str, dict[str, float]]) -> Path:
    """The nested file: ``left`` (a) and ``right`` (b) systems, parameters through an .ssv and .ssm on the top."""
    ssd, connection = _pyssp()

    def link(start: str, end: str, transformation=None):
        (se, _, sc), (ee, _, ec) = start.rpartition("."), end.rpartition(".")
        made = connection(start_element=se or None, start_connector=sc, end_element=ee or None, end_connector=ec)
        made.transformation = transformation
        return made

    def build(archive, ssd_file) -> None:
        a, b = parameters["a"], parameters["b"]
        left = ssd.System(name="left")
        left.connectors = _system_connectors(ssd, {"F": ("input", "N"), "x": ("output", "cm"), "v": ("output", "m/s")})
        a_d = _inline(ssd, {"d": 2 * a["d"]}, "a_damping")  # the top's binding wins over this one
        left.elements = [_component(ssd, "a", f"resources/{fmus['a'].name}", ["F", "x", "v", *a], a_d)]
        left.connections = [link("F", "a.F"), link("a.x", "x"), link("a.v", "v")]
        right = ssd.System(name="right")
        ports = {"x_in": ("input", "m"), "v_in": ("input", "m/s"), "F_c": ("output", "N")}
        right.connectors = _system_connectors(ssd, ports)
        right.elements = [_component(ssd, "b", f"resources/{fmus['b'].name}", [*ports, *b])]
        right.connections = [link("x_in", "b.x_in"), link("v_in", "b.v_in"), link("b.F_c", "F_c")]
        right.parameter_bindings = [_inline(ssd, {k: b[k] for k in ("m", "d", "c_c", "d_c")}, "b", prefix="b.")]
        top = ssd.System(name="oscillators")
        top.elements = [left, right]
        top.connections = [link("left.x", "right.x_in"), link("left.v", "right.v_in")]
        top.connections.append(link("right.F_c", "left.F", _linear(*FORCE)))
        top.parameter_bindings = [_top_binding(ssd, archive, a, b)]
        ssd_file.system = top
        _units(ssd_file)

    return _write(out, fmus, build)


def _top_binding(ssd, archive, a: dict[str, float], b: dict[str, float]):
    """The top system's binding: ``resources/oscillators.ssv`` (a's mass in grams, b's stiffness by another
    name, a's other parameters by their paths) through ``resources/oscillators.ssm``."""
    from pyssp_standard.ssm import SSM

    values = {"mass_a_g": GRAMS, **{f"left.a.{k}": v for k, v in a.items() if k != "m"}, "stiffness_b": b["c"]}
    with SSM(archive.unpacked_path / "resources" / "oscillators.ssm", mode="w") as mapping:
        grams = _linear(TO_KG, 0.0)
        mapping.add_mapping("mass_a_g", "left.a.m", suppress_unit_conversion=True, transformation=grams)
        mapping.add_mapping("stiffness_b", "right.b.c")
    return ssd.ParameterBinding(
        source=_parameter_file(archive, "oscillators.ssv", values),
        parameter_mapping=ssd.ParameterMapping(source="resources/oscillators.ssm"),
    )


def run_heliostep(path: Path, cache: Path, h: float, stop: float, outputs) -> tuple[np.ndarray, np.ndarray]:
    """heliostep's run of the SSP ``path``: its system read (:func:`heliostep.fmu.ssp.read_ssp`), each component
    a sampled Co-Simulation FMU at ``h``; (the communication points, the ``outputs`` there, one column each)."""
    from heliostep.cosim import Connection, CoSimulation, read_fmu
    from heliostep.fmu.ssp import read_ssp

    read = read_ssp(path, cache)
    system = CoSimulation(
        {name: read_fmu(fmu, co_simulation=True) for name, fmu in read.fmus.items()},
        [Connection(s, t, read.transformations.get(t)) for s, t in read.connections],
        parameters=read.parameters,
        communication_intervals=dict.fromkeys(read.fmus, h),
    )
    trace = system.simulate(0.0, stop).trace
    times = trace["time"].to_numpy()
    last = np.r_[times[1:] != times[:-1], True] & (times > 0.0)  # the row after each point's event
    return times[last], trace.loc[last, list(outputs)].to_numpy()


def run_libcosim(path: Path, h: float, stop: float, outputs) -> tuple[np.ndarray, np.ndarray]:
    """libcosim's run of the same file (``libcosimpy``'s SSP execution, its fixed-step algorithm at ``h``)."""
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.WARNING)
    nanos = round(h * 1e9)
    steps = round(stop * 1e9) // nanos
    execution = CosimExecution.from_ssp_file(str(path), step_size=nanos)
    slaves = {info.name.decode(): info.index for info in execution.slave_infos()}
    observer = CosimObserver.create_time_series(buffer_size=steps + 2)
    execution.add_observer(observer)
    columns = []
    for output in outputs:
        instance, variable = output.split(".", 1)
        refs = {v.name.decode(): v.reference for v in execution.slave_variables(slaves[instance])}
        columns.append((slaves[instance], refs[variable]))
        observer.start_time_series(*columns[-1], CosimVariableType.REAL)
    execution.simulate_until(round(stop * 1e9))
    values = []
    for slave, ref in columns:  # from step 1: libcosimpy drops a sample per step number 0 it returns
        nanos_at, _, samples = observer.time_series_real_samples(slave, ref, from_step=1, sample_count=steps)
        values.append(samples)
    return np.asarray(nanos_at) * 1e-9, np.array(values).T
