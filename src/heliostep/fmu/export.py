"""Export a flat model (:mod:`heliostep.fmu.modelica`) as an FMI 2.0 or 3.0 Model Exchange FMU.

CasADi solves the implicit residual for the derivatives (explicit code where the equations sort,
else a Newton iteration in C) and generates C; one FMI layer per version compiles it; the
modelDescription's dependencies come from CasADi's sparsity; the zip has fixed time stamps.

Details: docs/fmus.md, ``heliostep.fmu.export``.
"""

from __future__ import annotations

import shutil
import subprocess
import zipfile
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

from heliostep._version import __version__
from heliostep.errors import RunFailure
from heliostep.fmu.model_xml import Layout, build_description_fmi3, model_description, model_description_fmi3
from heliostep.fmu.modelica import FlatModel, ModelicaError

if TYPE_CHECKING:  # casadi is imported where an FMU is built: a run of built FMUs needs none of it
    import casadi as ca

#: The everyday solve: exactly two Newton steps from the previous solution, never stopping
#: early on an absolute residual test. A warm start that is already "close enough" would
#: otherwise be returned unchanged, and CVODE's difference-quotient Jacobian (states perturbed
#: by ~1e-8) would see no change at all. Two steps are exact for residuals linear in the
#: unknowns and leave an error of the order of (change since the last call)^4 otherwise.
POLISH_OPTIONS = {"abstol": 0.0, "abstolStep": 0.0, "max_iter": 2, "error_on_fail": False}
#: The fallback when the polish does not satisfy the residual (first call, large jumps).
ROBUST_OPTIONS = {"abstol": 1e-12, "abstolStep": 1e-14, "max_iter": 50, "error_on_fail": False}

FMI_LAYER = "fmi2_model_exchange.c"
SOURCE_FILES = (FMI_LAYER, "equations.c")
FMI2_PLATFORM = "linux64"
#: The FMI versions an FMU can be exported as, each with its C layer (written once for all models)
#: and its binaries folder (FMI 2.0: ``linux64``; FMI 3.0, its platform tuple: ``x86_64-linux``).
FMI_LAYERS = {2: FMI_LAYER, 3: "fmi3_model_exchange.c"}
PLATFORMS = {2: FMI2_PLATFORM, 3: "x86_64-linux"}
#: What both layers include: the state machine, the checks, the evaluation and the entry points' bodies.
LAYER_CORE = "model_exchange_core.h"


class BuildError(RunFailure):
    """The C compiler or the packaging of an FMU failed (a run failure: exit status 1)."""


def equation_functions(model: FlatModel) -> tuple[ca.Function, ca.Function, ca.Function, ca.Function]:
    """CasADi functions ``model_eval``, ``model_solve``, ``model_scale`` and ``model_start`` of a flat model.

    ``model_eval`` is explicit code where the equations sort (:func:`explicit_evaluation`), else
    it polishes the previous solution with two Newton steps; ``model_solve`` iterates to
    convergence first (for a cold or far start), then polishes the same way. ``model_scale``
    gives the size of the terms each equation balances, for the C layer's residual check (which
    computes it only when a residual is not negligible outright).
    """
    import casadi as ca

    unknowns, (x, u, p) = _unknowns_and_known(model)
    known = ca.vertcat(model.time, x, u, p)
    residual_fn = residual_function(model)
    n_unknowns = unknowns.numel()
    guess = ca.MX.sym("guess", n_unknowns + len(model.calculated_parameters))

    # The size of what each equation balances, in its own units, so that its residual is judged
    # relative to its own terms rather than by one absolute 1e-6: |F_i| + sum_k |dF_i/dk_k| |k_k|
    # over the known values, with the unknowns at zero (never inflated by a wrong solution).
    magnitude = ca.fabs(model.residual) + ca.mtimes(ca.fabs(ca.jacobian(model.residual, known)), ca.fabs(known))
    scale_fn = ca.Function("scale", [unknowns, known], [magnitude])
    no_unknowns = ca.MX.zeros(unknowns.numel(), 1)
    polish = ca.rootfinder("polish", "fast_newton", residual_fn, POLISH_OPTIONS)
    robust = ca.rootfinder("robust", "fast_newton", residual_fn, ROBUST_OPTIONS)
    calculated = ca.vertcat(*model.calculated_parameter_values) if model.calculated_parameters else ca.MX(0, 1)

    def solve(name: str, solution: ca.MX) -> ca.Function:
        return ca.Function(
            name,
            [model.time, x, u, p, guess],
            [ca.vertcat(solution, calculated), residual_fn(solution, known)],
            ["t", "x", "u", "p", "guess"],
            ["computed", "residual"],
        )

    converge = solve("model_solve", polish(robust(guess[:n_unknowns], known), known))
    explicit = explicit_evaluation(model, residual_fn, calculated)
    evaluate = explicit if explicit is not None else solve("model_eval", polish(guess[:n_unknowns], known))
    scale = ca.Function(
        "model_scale", [model.time, x, u, p], [scale_fn(no_unknowns, known)], ["t", "x", "u", "p"], ["scale"]
    ).expand()
    start = ca.Function(
        "model_start", [p], [ca.vertcat(*model.state_start) if model.states else ca.MX(0, 1)], ["p"], ["x0"]
    )
    if start.has_free():
        raise ModelicaError(
            f"{model.source_file}: start values of {model.name} depend on non-parameters: {start.free_mx()}"
        )
    return evaluate, converge, scale, start


def _unknowns_and_known(model: FlatModel) -> tuple[ca.MX, tuple[ca.MX, ca.MX, ca.MX]]:
    """The model's unknowns (derivatives, then algebraic variables) and its states, inputs and parameters."""
    import casadi as ca

    stack = lambda variables: ca.vertcat(*[model.symbols[v.name] for v in variables])  # noqa: E731
    unknowns = ca.vertcat(stack(model.derivatives), stack(model.algebraics))
    return unknowns, (stack(model.states), stack(model.inputs), stack(model.parameters))


def _sx_known(model: FlatModel) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
    """SX symbols of the known values t, x, u, p, sized as the model's (the explicit functions' inputs)."""
    import casadi as ca

    sizes = [model.time.numel(), len(model.states), len(model.inputs), len(model.parameters)]
    t, x, u, p = (ca.SX.sym(name, size) for name, size in zip("txup", sizes))
    return t, x, u, p


def residual_function(model: FlatModel) -> ca.Function:
    """``residual(unknowns, known)``: the model's implicit residual F, known = (t, x, u, p)."""
    import casadi as ca

    unknowns, (x, u, p) = _unknowns_and_known(model)
    return ca.Function("residual", [unknowns, ca.vertcat(model.time, x, u, p)], [model.residual])


def sequential_solution(residual: ca.SX, unknowns: ca.SX) -> list[ca.SX] | None:
    """The unknowns solved one equation at a time, as Modelica tools sort a model (BLT), or None.

    Repeatedly takes an equation in which exactly one unknown is left and which is affine in it,
    ``F_i = a u_j + b`` with ``a`` and ``b`` free of ``u_j``, solves it, ``u_j = -b / a``, and
    substitutes the solution into the equations left. Returns the unknowns' expressions in the
    known values, or None when some equations are left (a system of several unknowns, or one
    nonlinear in its unknown): those models keep the Newton solve.
    """
    import casadi as ca

    n = unknowns.numel()
    equations = [residual[i] for i in range(n)]
    solution: dict[int, ca.SX] = {}
    left = list(range(n))
    while left:
        for i in left:
            free = [j for j in range(n) if j not in solution and ca.depends_on(equations[i], unknowns[j])]
            if len(free) != 1:
                continue
            j = free[0]
            slope = ca.jacobian(equations[i], unknowns[j])
            if ca.depends_on(slope, unknowns[j]):
                continue
            solution[j] = -ca.substitute(equations[i], unknowns[j], ca.SX(0)) / slope
            left.remove(i)
            for k in left:
                equations[k] = ca.substitute(equations[k], unknowns[j], solution[j])
            break
        else:
            return None
    return [solution[j] for j in range(n)] if len(solution) == n else None


def explicit_evaluation(model: FlatModel, residual_fn: ca.Function, calculated: ca.MX) -> ca.Function | None:
    """``model_eval`` as explicit code where :func:`sequential_solution` solves the model, else None.

    Same inputs and outputs as the Newton form (``guess`` unused): the derivatives and
    algebraic variables computed straight from the known values, with no iteration, so each
    evaluation costs the model's own arithmetic; the residual is still returned for the C
    layer's check.
    """
    import casadi as ca

    t, x, u, p = _sx_known(model)
    n_unknowns = len(model.derivatives) + len(model.algebraics)
    guess = ca.SX.sym("guess", n_unknowns + len(model.calculated_parameters))
    known = ca.vertcat(t, x, u, p)
    unknowns = ca.SX.sym("unknowns", n_unknowns)
    residual = residual_fn.expand()  # SX: the sorting substitutes expressions
    solution = sequential_solution(residual(unknowns, known), unknowns)
    if solution is None:
        return None
    solved = ca.vertcat(*solution) if solution else ca.SX(0, 1)
    parameters = ca.vertcat(*[model.symbols[v.name] for v in model.parameters])
    values = (
        ca.Function("calculated", [parameters], [calculated]).expand()(p)
        if model.calculated_parameters
        else ca.SX(0, 1)
    )
    return ca.Function(
        "model_eval",
        [t, x, u, p, guess],
        [ca.vertcat(solved, values), residual(solved, known)],
        ["t", "x", "u", "p", "guess"],
        ["computed", "residual"],
    )


def state_part(evaluate: ca.Function) -> tuple[ca.Function | None, list[int]]:
    """``model_state_part(t, x, u, p)``: the computed variables that depend on no input, alone.

    For an explicit ``model_eval`` (straight-line code), the computed variables whose
    expressions are free of the inputs (from the Jacobian's sparsity), and a function that
    computes only them: CasADi keeps only the operations they need. The C layer uses it for an
    output that depends on the states alone (a mechanics model's angle and speed) while an
    input has changed since the last full evaluation, as Modelica tools evaluate only the
    equations an output needs. None (and no indices) for a Newton-solved model.
    """
    import casadi as ca

    if not evaluate.is_a("SXFunction"):
        return None, []
    on_inputs = set(evaluate.sparsity_jac(2, 0).row())
    indices = [i for i in range(evaluate.size1_out(0)) if i not in on_inputs]
    if not indices:
        return None, []
    t, x, u, p, guess = evaluate.sx_in()
    computed = evaluate(t, x, u, p, guess)[0]
    return ca.Function(
        "model_state_part",
        [t, x, u, p],
        [ca.vertcat(*[computed[i] for i in indices])],
        ["t", "x", "u", "p"],
        ["computed"],
    ), indices


def rest_evaluation(model: FlatModel, part_indices: list[int]) -> tuple[ca.Function | None, list[int], list[int]]:
    """``model_rest(t, x, u, p, part) -> (computed, residual)``: the computed variables that
    ``model_state_part`` leaves out, from its values.

    The C layer evaluates the state part for an output that depends on the states alone (the
    master reads a mechanics model's angle before it sets the new torque); a full ``model_eval``
    at the same state would compute that part again (its cos, tan and tanh). Here the part's
    unknowns are the inputs ``part`` (in :func:`state_part`'s order) and only the equations left
    are sorted (:func:`sequential_solution`), so each computed variable is the expression that
    ``model_eval`` builds, with the part's values where it has their expressions: the same bits
    (shown for the shipped models, ``tests/fmu/test_fmu_export.py``; the same equations solved in
    any case, so at worst a rounding apart). ``residual``: those equations'
    residuals at the solution, which the C layer checks as it checks ``model_eval``'s. Returns
    the function, the computed variables it gives and the equations it solves (their indices in
    F), or (None, [], []) when there is no state part, nothing is left, or the rest does not sort.
    """
    import casadi as ca

    n_unknowns = len(model.derivatives) + len(model.algebraics)
    given = [j for j in part_indices if j < n_unknowns]  # the part's unknowns (not its calculated parameters)
    rest = [i for i in range(n_unknowns) if i not in part_indices]
    if not given or not rest:
        return None, [], []
    t, x, u, p = _sx_known(model)
    part = ca.SX.sym("part", len(part_indices))
    unknowns = ca.SX.sym("unknowns", n_unknowns)
    residual = residual_function(model).expand()(unknowns, ca.vertcat(t, x, u, p))
    residual = ca.substitute(
        residual,
        ca.vertcat(*[unknowns[j] for j in given]),
        ca.vertcat(*[part[part_indices.index(j)] for j in given]),
    )
    wanted = ca.vertcat(*[unknowns[i] for i in rest])
    equations = [i for i in range(n_unknowns) if ca.depends_on(residual[i], wanted)]
    if len(equations) != len(rest):
        return None, [], []
    system = ca.vertcat(*[residual[i] for i in equations])
    solution = sequential_solution(system, wanted)
    if solution is None:
        return None, [], []
    solved = ca.vertcat(*solution)
    function = ca.Function(
        "model_rest",
        [t, x, u, p, part],
        [solved, ca.substitute(system, wanted, solved)],
        ["t", "x", "u", "p", "part"],
        ["computed", "residual"],
    )
    return function, rest, equations


def _c_double(value: float | None) -> str:
    return repr(float(value or 0.0))


def _c_array(ctype: str, name: str, values: list[str]) -> str:
    body = ", ".join(values) if values else "0"
    return f"static const {ctype} {name}[{max(len(values), 1)}] = {{{body}}};\n"


def model_header(
    model: FlatModel,
    layout: Layout,
    guid: str,
    explicit: bool,
    state_part_indices: list[int],
    rest: tuple[list[int], list[int]] = ([], []),
) -> str:
    """The per-model ``model.h`` read by the FMI layer (``explicit``: ``model_eval`` needs no
    Newton iteration, see :func:`explicit_evaluation`; ``state_part_indices``: the computed
    variables ``model_state_part`` computes, see :func:`state_part`; ``rest``: the computed
    variables and the equations of ``model_rest``, see :func:`rest_evaluation`)."""
    rest_indices, rest_equations = rest
    starts = []
    for v in layout.variables:
        starts.append(_c_double(v.start) if v.kind in ("parameter", "state", "input") else "0.0")
    names = ['"' + v.name.replace("\\", "\\\\").replace('"', '\\"') + '"' for v in layout.variables]
    n_computed = len(model.derivatives) + len(model.algebraics) + len(model.calculated_parameters)
    return (
        f"/* generated by heliostep {__version__} for {model.name}; do not edit */\n"
        "#ifndef HELIOSTEP_MODEL_H\n#define HELIOSTEP_MODEL_H\n"
        f'#define MODEL_IDENTIFIER_STRING "{model.name}"\n'
        f'#define MODEL_GUID "{guid}"\n'
        f"#define N_PARAMETERS {len(model.parameters)}\n"
        f"#define N_STATES {len(model.states)}\n"
        f"#define N_INPUTS {len(model.inputs)}\n"
        f"#define N_UNKNOWNS {len(model.derivatives) + len(model.algebraics)}\n"
        f"#define N_COMPUTED {n_computed}\n"
        f"#define EXPLICIT_EVAL {int(explicit)}\n"
        f"#define N_STATE_PART {len(state_part_indices)}\n"
        + _c_array("int", "STATE_PART_INDEX", [str(i) for i in state_part_indices])
        + _c_array("char", "IN_STATE_PART", ["1" if i in state_part_indices else "0" for i in range(n_computed)])
        + f"#define N_REST {len(rest_indices)}\n"
        + _c_array("int", "REST_INDEX", [str(i) for i in rest_indices])
        + _c_array("int", "REST_EQUATION", [str(i) for i in rest_equations])
        + _c_array("double", "START_VALUES", starts)
        + _c_array("char", "STATE_START_CALCULATED", ["1" if v.start is None else "0" for v in model.states])
        + _c_array("double", "STATE_NOMINALS", [_c_double(v.nominal or 1.0) for v in model.states])
        + _c_array("char *const", "VARIABLE_NAMES", names)
        + "#endif\n"
    )


def fmi_headers_dir() -> Path:
    """The folder of FMI 2.0 and 3.0 headers that fmpy ships (``fmpy/c-code``)."""
    import fmpy

    path = Path(fmpy.__file__).parent / "c-code"
    for header in ("fmi2Functions.h", "fmi3Functions.h"):
        if not (path / header).exists():
            raise BuildError(f"{path}: the FMI header {header} of fmpy was not found")
    return path


def compiler() -> str:
    for name in ("gcc", "cc"):
        path = shutil.which(name)
        if path:
            return path
    raise BuildError("no C compiler found: install gcc (Debian: apt-get install gcc)")


def _run(command: list[str], what: str) -> None:
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        raise BuildError(f"{what} failed:\n{result.stdout}{result.stderr}")


def compile_binary(source_dir: Path, library: Path, source_files: tuple[str, ...] = SOURCE_FILES) -> None:
    """Compile the FMI layer and the generated equations (``source_files``) into a shared library."""
    cc = compiler()
    common = [
        "-std=c99",
        "-O2",
        "-fPIC",
        "-fvisibility=hidden",
        "-Wall",
        "-Wextra",
        "-Werror",
        f"-I{fmi_headers_dir()}",
        f"-I{source_dir}",
    ]
    objects = []
    for name in source_files:
        extra = []
        if name == "equations.c":
            # CasADi's generated code keeps unused 'mem' arguments in its calling convention
            extra = ["-Wno-unused-parameter", "-DCASADI_SYMBOL_EXPORT="]
        obj = source_dir / (Path(name).stem + ".o")
        _run([cc, *common, *extra, "-c", str(source_dir / name), "-o", str(obj)], f"compiling {name}")
        objects.append(str(obj))
    library.parent.mkdir(parents=True, exist_ok=True)
    _run([cc, "-shared", "-o", str(library), *objects, "-lm"], f"linking {library.name}")


def write_zip(fmu_path: Path, files: dict[str, Path]) -> None:
    """Zip ``files`` (archive name → file) with fixed time stamps, in name order."""
    with zipfile.ZipFile(fmu_path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name in sorted(files):
            info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            archive.writestr(info, files[name].read_bytes())


def export_fmu(
    model: FlatModel, fmu_path: Path, guid: str, work_dir: Path, generation_tool: str, fmi_version: int = 2
) -> Path:
    """Generate, compile and zip ``model`` into ``fmu_path`` (written whole or not at all), an FMI
    ``fmi_version`` (2 or 3) Model Exchange FMU; ``guid`` is its GUID (FMI 3.0: instantiation token).

    ``work_dir`` must be on the same file system as ``fmu_path``.
    """
    import casadi as ca

    layer_name, platform = FMI_LAYERS[fmi_version], PLATFORMS[fmi_version]
    source_files = (layer_name, "equations.c")
    work_dir = Path(work_dir)
    sources = work_dir / "sources"
    sources.mkdir(parents=True, exist_ok=True)
    layout = Layout.of(model)
    evaluate, converge, scale, start = equation_functions(model)
    partial, partial_indices = state_part(evaluate)
    rest, rest_indices, rest_equations = rest_evaluation(model, partial_indices) if partial else (None, [], [])

    generator = ca.CodeGenerator("equations.c", {"with_header": True, "casadi_real": "double"})
    for function in (evaluate, converge, scale, start, partial, rest):
        if function is not None:
            generator.add(function)
    generator.generate(str(sources) + "/")
    header = model_header(
        model, layout, guid, evaluate.is_a("SXFunction"), partial_indices, (rest_indices, rest_equations)
    )
    (sources / "model.h").write_text(header)
    layer = resources.files("heliostep.fmu") / "c" / layer_name
    (sources / layer_name).write_bytes(layer.read_bytes())
    (sources / LAYER_CORE).write_bytes((resources.files("heliostep.fmu") / "c" / LAYER_CORE).read_bytes())

    library = work_dir / "binaries" / platform / f"{model.name}.so"
    compile_binary(sources, library, source_files)
    description = work_dir / "modelDescription.xml"
    describe = model_description if fmi_version == 2 else model_description_fmi3
    description.write_bytes(describe(model, layout, guid, evaluate, generation_tool, source_files))

    files = {"modelDescription.xml": description, f"binaries/{platform}/{model.name}.so": library}
    if fmi_version == 3:  # FMI 3.0 lists the sources in sources/buildDescription.xml
        build_description = sources / "buildDescription.xml"
        build_description.write_bytes(build_description_fmi3(model.name, source_files))
        files["sources/buildDescription.xml"] = build_description
    for name in (*source_files, LAYER_CORE, "equations.h", "model.h"):
        files[f"sources/{name}"] = sources / name
    files[f"sources/{model.source_file.name}"] = model.source_file
    built = work_dir / f"{model.name}.fmu"
    write_zip(built, files)
    built.replace(fmu_path)  # work_dir is on the same file system: an atomic move
    return fmu_path
