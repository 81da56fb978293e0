"""The two error families (issue #19): every exception class heliostep defines is an input error
(exit 2) or a run failure (exit 1), never both, and the command line maps them so."""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import heliostep
from heliostep.cli import main
from heliostep.errors import HeliostepError, InputError, RunFailure


def _error_classes() -> list[type]:
    found = {}
    for module in pkgutil.walk_packages(heliostep.__path__, "heliostep."):
        if module.name.startswith("heliostep.data"):
            continue
        loaded = importlib.import_module(module.name)
        for _, value in inspect.getmembers(loaded, inspect.isclass):
            if issubclass(value, HeliostepError) and value.__module__.startswith("heliostep"):
                found[f"{value.__module__}.{value.__qualname__}"] = value
    return list(found.values())


def test_every_error_class_is_in_exactly_one_family():
    classes = _error_classes()
    names = {c.__name__ for c in classes}
    # the ones a reader would look for first must be found by the walk
    assert {
        "InputError",
        "RunFailure",
        "BuildError",
        "FMIError",
        "SimulationError",
        "TraceWriteError",
        "RunFailed",
        "ModelicaError",
    } <= names, names
    for cls in classes:
        if cls is HeliostepError:
            continue
        assert issubclass(cls, InputError) != issubclass(cls, RunFailure), cls


def test_the_command_line_exits_1_for_a_run_failure_and_2_for_an_input_error(monkeypatch, capsys):

    def fail(args):
        raise RunFailure("gcc died")

    def bad(args):
        raise InputError("fmus.motor: no such model")

    parser_func = {"fail": fail, "bad": bad}
    for name, expected in (("fail", 1), ("bad", 2)):
        monkeypatch.setattr("heliostep.cli.make_parser", _parser_with(parser_func[name]))
        assert main(["x"]) == expected
        assert capsys.readouterr().err.count("\n") == 1  # one line, no traceback


def _parser_with(func):
    import argparse

    def make_parser(argv=None):
        parser = argparse.ArgumentParser(prog="heliostep")
        sub = parser.add_subparsers(dest="command")
        sub.add_parser("x").set_defaults(func=func)
        return parser

    return make_parser


def test_nothing_raises_the_bare_base_class():
    # a bare HeliostepError would be in neither family (the CLI then falls back to exit 2)
    import ast
    from pathlib import Path

    offenders = []
    for path in Path(heliostep.__file__).parent.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Raise) and node.exc is not None:
                call = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
                if isinstance(call, ast.Name) and call.id == "HeliostepError":
                    offenders.append(f"{path.name}:{node.lineno}")
    assert not offenders, offenders
