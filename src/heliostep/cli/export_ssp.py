"""``heliostep export-ssp``: a scenario's system (FMUs, connections, parameters) as an SSP 1.0 file."""

from __future__ import annotations

import argparse

from heliostep.fmu.ssp import write_ssp
from heliostep.results.output.files import check_out_name, refuse_link
from heliostep.run.fmus import resolve_fmus
from heliostep.scenario import load_scenario


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "export-ssp",
        help="write a scenario's FMUs, connections and parameters as an SSP 1.0 file",
        description="Write the scenario's system as SSP 1.0 (SystemStructure.ssd and resources/INSTANCE.fmu): "
        "every FMU instance a component with its inputs, outputs and parameters as connectors, the connections, "
        "the scenario's parameters as parameter bindings. A scenario with 'system: FILE.ssp' reads it back.",
    )
    parser.add_argument("scenario", help="scenario YAML file or the name of a shipped scenario")
    parser.add_argument("--out", required=True, metavar="FILE.ssp", help="the SSP file to write")
    parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE", help="override a scenario key"
    )
    parser.set_defaults(func=_run_export)


def _run_export(args: argparse.Namespace) -> int:
    out = check_out_name(args.out)
    refuse_link(out)  # a link there is not heliostep's: neither written through nor replaced
    scenario = load_scenario(args.scenario, args.overrides)
    fmus = resolve_fmus(scenario)  # built or found, as a run would
    pairs = scenario.connection_pairs()
    transformations = {t: transform for _, t in pairs if (transform := scenario.transformation(t)) is not None}
    print(write_ssp(out, scenario.name, fmus, pairs, scenario.parameters, transformations))
    return 0
