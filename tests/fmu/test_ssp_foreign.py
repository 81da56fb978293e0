"""SSP 1.0 files written by another tool: pyssp-standard's writers (``tests/support/foreign_ssp.py``), read by
heliostep and run by heliostep and by libcosim (``libcosimpy``'s SSP execution) from the same file.

The facts asserted come from what the test gave pyssp-standard to write (and pyssp-standard's own reader):
the components, connections, parameter values and transformations of the flat file, the same system from the
nested file (flattened; the mass given in grams mapped to kg by the .ssm's factor; the top's binding over the
component's; m -> cm -> m through ``left.x``). Runs: both masters step the two Co-Simulation oscillators at
h = 1 ms over 1 s (Jacobi, the force's ``factor * F_c + offset`` passed at each point); the outputs agree at
every communication point to 1e-12 (measured: 1.5e-14, on outputs up to 6), as the two-oscillator oracle of
``tests/cosim/test_libcosim_oracle.py`` without the SSP.
"""

from __future__ import annotations

import zipfile

import numpy as np
import pytest

import foreign_ssp
import two_oscillators
from foreign_ssp import FORCE, GRAMS, NESTED, OUTPUTS, TO_KG
from heliostep.errors import InputError
from heliostep.fmu.ssp import read_ssp

H, STOP = 1e-3, 1.0


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """The FMUs and the two files pyssp-standard writes: {"fmus": ..., "flat": path, "nested": path}."""
    folder = tmp_path_factory.mktemp("foreign_ssp")
    fmus = two_oscillators.build(folder / "fmus")
    parameters = two_oscillators.PARAMETERS
    return {
        "fmus": fmus,
        "flat": foreign_ssp.write_flat(folder / "flat.ssp", fmus, parameters),
        "nested": foreign_ssp.write_nested(folder / "nested.ssp", fmus, parameters),
    }


def test_the_flat_file_reads_as_pyssp_standard_wrote_it(written, tmp_path):
    from pyssp_standard import SSP

    with SSP(written["flat"], mode="r") as archive, archive.system_structure as ssd:
        theirs = ({e.name for e in ssd.system.elements}, len(ssd.system.connections))
    assert theirs == ({"a", "b"}, 3)
    with zipfile.ZipFile(written["flat"]) as archive:
        assert 'generationTool="pyssp_standard"' in archive.read("SystemStructure.ssd").decode()
        assert "resources/a.ssv" in archive.namelist()
    system = read_ssp(written["flat"], tmp_path)
    assert set(system.fmus) == {"a", "b"}
    assert system.connections == two_oscillators.CONNECTIONS
    assert system.parameters == two_oscillators.PARAMETERS  # a's from resources/a.ssv, b's inline
    assert system.transformations == {"a.F": FORCE}


def test_the_nested_file_flattens_to_the_same_system(written, tmp_path):
    system = read_ssp(written["nested"], tmp_path)
    a, b = NESTED["a"], NESTED["b"]
    assert set(system.fmus) == {a, b}
    assert sorted(system.connections) == sorted(
        (f"{NESTED[s[0]]}.{s[2:]}", f"{NESTED[t[0]]}.{t[2:]}") for s, t in two_oscillators.CONNECTIONS
    )
    expected = two_oscillators.PARAMETERS
    assert system.parameters[a]["m"] == GRAMS * TO_KG == expected["a"]["m"]  # .ssv in g, .ssm's factor
    assert system.parameters[a]["d"] == expected["a"]["d"]  # the top's binding, not the component's 2 d
    assert system.parameters == {a: expected["a"], b: expected["b"]}  # b's through right's prefix "b."
    # m -> cm (1 / 0.01, pint's cm) -> m (0.01): exactly (1, 0); the force's transformation as written
    assert system.transformations == {f"{a}.F": FORCE, f"{b}.x_in": (1.0, 0.0)}


@pytest.fixture(scope="module")
def libcosim_flat(written):
    pytest.importorskip("libcosimpy", reason="libcosimpy (libcosim's PyPI package) does not install on this platform")
    return foreign_ssp.run_libcosim(written["flat"], H, STOP, (*OUTPUTS, "a.F"))


def test_heliostep_runs_the_flat_file_as_libcosim_does(written, libcosim_flat, tmp_path):
    theirs_at, theirs = libcosim_flat
    force, pushed = theirs[:, -1], theirs[:, OUTPUTS.index("b.F_c")]
    assert np.array_equal(force[1:], FORCE[0] * pushed[:-1] + FORCE[1])  # libcosim transforms it (a point later)
    ours_at, ours = foreign_ssp.run_heliostep(written["flat"], tmp_path, H, STOP, OUTPUTS)
    assert len(ours_at) == len(theirs_at) == round(STOP / H)
    assert np.max(np.abs(ours_at - theirs_at)) <= 1e-12
    assert np.max(np.abs(ours - theirs[:, :-1])) <= 1e-12
    assert np.max(np.abs(ours), axis=0) == pytest.approx([0.1, 1.06, 0.049, 0.47, 5.96], rel=0.02)  # it moves


def test_heliostep_runs_the_nested_file_as_libcosim_runs_the_flat_one(written, libcosim_flat, tmp_path):
    outputs = [f"{NESTED[name[0]]}.{name[2:]}" for name in OUTPUTS]
    ours_at, ours = foreign_ssp.run_heliostep(written["nested"], tmp_path, H, STOP, outputs)
    theirs_at, theirs = libcosim_flat
    assert np.max(np.abs(ours_at - theirs_at)) <= 1e-12
    assert np.max(np.abs(ours - theirs[:, :-1])) <= 1e-12


#: a loop of direct feedthrough between the two Co-Simulation FMUs (F_c depends on x_in at once), and the
#: positions pushing each other through the force inputs
LOOP = [("a.F_c", "b.x_in"), ("b.F_c", "a.x_in"), ("a.x", "b.F"), ("b.x", "a.F")]
LOOP_PARAMETERS = {"a": {"m": 1.0, "c": 100.0, "x0": 0.1, "c_c": 0.5}, "b": {"m": 2.0, "c": 60.0, "c_c": 0.5}}


def _no_units(ssd, system) -> None:
    """The connectors without units (the loop joins a force to a position, which heliostep would convert)."""
    from pyssp_standard.common_content_ssc import TypeReal

    for element in system.elements:
        for connector in element.connectors:
            connector.type_ = TypeReal(None)


def test_a_loop_of_co_simulation_fmus_runs_as_libcosim_runs_it(written, tmp_path):
    """Jacobi: each FMU steps with the other's outputs of the point before, so the loop needs nothing solved."""
    pytest.importorskip("libcosimpy", reason="libcosimpy (libcosim's PyPI package) does not install on this platform")
    path = foreign_ssp.write_flat(
        tmp_path / "loop.ssp", written["fmus"], LOOP_PARAMETERS, change=_no_units, connections=LOOP
    )
    outputs = ("a.x", "a.F_c", "b.x", "b.F_c")
    theirs_at, theirs = foreign_ssp.run_libcosim(path, H, STOP, (*outputs, "a.x_in"))
    assert np.array_equal(theirs[1:, -1], theirs[:-1, outputs.index("b.F_c")])  # the loop's value a point late
    ours_at, ours = foreign_ssp.run_heliostep(path, tmp_path, H, STOP, outputs)
    assert np.max(np.abs(ours_at - theirs_at)) <= 1e-12
    assert np.max(np.abs(ours - theirs[:, :-1])) <= 1e-12
    assert np.max(np.abs(ours[:, 1])) > 0.01  # the coupling force moves


def test_units_after_the_default_experiment_are_refused_naming_the_element_and_the_file(written, tmp_path):
    """pyssp-standard writes ``ssd:Units`` after ``ssd:DefaultExperiment``; SSP 1.0's schema has them before."""
    path = foreign_ssp.write_flat(tmp_path / "units.ssp", written["fmus"], two_oscillators.PARAMETERS, units=True)
    with pytest.raises(InputError) as caught:
        read_ssp(path, tmp_path)
    assert str(path) in str(caught.value)
    assert "not a valid SSP 1.0 file" in str(caught.value)
    assert "SystemStructureDescription}Units': This element is not expected" in str(caught.value)


def _nested_ssd_component(ssd, system) -> None:
    inner = ssd.Component()
    inner.name, inner.component_type, inner.source = "inner", "application/x-ssp-definition", "inner.ssd"
    system.elements.append(inner)


def _binding_inside_the_fmu(ssd, system) -> None:
    system.elements[1].parameter_bindings.append(
        ssd.ParameterBinding(source="resources/b.ssv", source_base="component")
    )


@pytest.mark.parametrize(
    ("change", "said"),
    [
        (_nested_ssd_component, "ssd:Component 'inner' is of type 'application/x-ssp-definition', not an FMU"),
        (_binding_inside_the_fmu, "ssd:ParameterBinding of ssd:Component 'b': sourceBase=\"component\""),
    ],
)
def test_what_heliostep_does_not_take_is_refused_naming_the_element_and_the_file(written, tmp_path, change, said):
    path = foreign_ssp.write_flat(tmp_path / "refused.ssp", written["fmus"], two_oscillators.PARAMETERS, change=change)
    with pytest.raises(InputError) as caught:
        read_ssp(path, tmp_path)
    assert str(caught.value).startswith(f"{path}: ")
    assert said in str(caught.value)
