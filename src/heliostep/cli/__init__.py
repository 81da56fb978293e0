"""The ``heliostep`` command line: argument parsing and exit codes only.

Each command lives in its own module with a ``register(subparsers)``; this module assembles them and
turns an error into one line on stderr and an exit status. The installed command is :func:`console_main`.

Details: docs/running.md, ``heliostep.cli``.
"""

from __future__ import annotations

import argparse
import gc
import importlib
import os
import sys
from typing import NoReturn

from heliostep._version import __version__
from heliostep.cli.signals import ForcedStop, StopSignal, signals_end_the_command, signals_until_exit
from heliostep.cli.standard_streams import guard_standard_streams
from heliostep.errors import HeliostepError, InputError, RunFailure

#: The commands and the modules that provide them, in the order ``--help`` lists them.
COMMANDS = {
    "build-fmus": "heliostep.cli.build",
    "geometry": "heliostep.cli.geometry",
    "end-loss": "heliostep.cli.endloss",
    "scenarios": "heliostep.cli.scenarios",
    "run": "heliostep.cli.run",
    "compare": "heliostep.cli.compare",
    "regress": "heliostep.cli.regress",
    "sweep": "heliostep.cli.sweep",
    "size": "heliostep.cli.size",
    "motors": "heliostep.cli.motors",
    "field-light": "heliostep.cli.fieldlight",
    "export-ssp": "heliostep.cli.export_ssp",
}
COMMAND_MODULES = tuple(COMMANDS.values())


def make_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The parser of the command ``argv`` names, importing only that command's module (a command's
    modules are heavy to import: pvlib, Dask, matplotlib); every command's when ``argv``
    names none (``--help``, a mistyped command: argparse then lists them all)."""
    parser = argparse.ArgumentParser(
        prog="heliostep",
        description="Co-simulate the stepper drives of solar-tracking mirrors.",
    )
    parser.add_argument("--version", action="version", version=f"heliostep {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    words = sys.argv[1:] if argv is None else argv
    named = next((word for word in words if not word.startswith("-")), None)
    modules = [COMMANDS[named]] if named in COMMANDS else list(dict.fromkeys(COMMAND_MODULES))
    for name in modules:
        importlib.import_module(name).register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    """The command ``argv`` names (default ``sys.argv[1:]``) run; its exit status."""
    # first thing: a stop signal while the commands' modules are imported is one line and 128 + its
    # number, never a traceback
    command = "heliostep"
    try:
        with signals_end_the_command() as starting:
            parser = make_parser(argv)
            args = parser.parse_args(argv)
            if not getattr(args, "func", None):
                parser.print_help()
                return 2
            command = starting.command = f"heliostep {args.command}"
            starting.at_once = False  # from here a signal raises StopSignal: the finally blocks run
            return _run(command, args)
    except StopSignal as stopped:
        print(f"{command}: stopped by {stopped} before it could finish", file=sys.stderr)
        return stopped.exit_status


def _check_current_folder() -> None:
    """Relative paths (``--out``, scenarios, ``fmus/``) resolve against the current folder: one that was
    deleted under the shell is refused before the command starts."""
    try:
        os.getcwd()
    except FileNotFoundError:
        raise InputError("the current folder no longer exists (deleted); cd to an existing folder") from None


def _run(command: str, args: argparse.Namespace) -> int:
    """The command's function, its errors as one line and an exit status."""
    try:
        _check_current_folder()
        return int(args.func(args) or 0)
    except HeliostepError as exc:
        status = 1 if isinstance(exc, RunFailure) else 2
        print(f"{command}: error: {exc}", file=sys.stderr)
        if "\n" in str(exc).strip():  # logs and CI show the last line: it names the error's subject too
            print(f"{command}: error (exit {status}) above: {_subject(str(exc))}", file=sys.stderr)
        return status
    except KeyboardInterrupt:
        print(f"{command}: interrupted", file=sys.stderr)
        return 130
    except (ForcedStop, Exception) as exc:  # a second stop signal: left at once, temporary files removed
        forced = _forced_stop(exc)  # raised by the handler, perhaps inside C code that wrapped it (an import)
        if forced is None:
            raise
        print(
            f"{command}: stopped by {forced}: exited without finishing the clean-up "
            f"(no file was left claiming to be complete)",
            file=sys.stderr,
        )
        return forced.exit_status


def _subject(message: str) -> str:
    """A long error's first line, shortened to what it names: its file or key and the start of its reason."""
    first = message.strip().splitlines()[0]
    return first if len(first) <= 160 else first[:157] + "..."


def _forced_stop(exc: BaseException | None) -> ForcedStop | None:
    """The :class:`ForcedStop` that ``exc`` is, or that caused it (an extension module's import, for one, turns
    an exception raised during its initialization into ``ImportError`` caused by it); None when neither."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, ForcedStop):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def console_main() -> NoReturn:
    """The installed ``heliostep`` command (``[project.scripts]``): :func:`main`, then its exit status.

    What is alive when the command has returned is frozen (:func:`gc.freeze`) before the interpreter exits:
    its finalization then frees those objects as usual but its full garbage collections no longer
    traverse every object of the imported libraries, which made up most of the exit's time. A stop
    signal after the command has returned does not interrupt the exit (:func:`signals_until_exit`). A standard
    output that fails does not change the exit status (:func:`guard_standard_streams`)."""
    signals_until_exit()
    guard_standard_streams()
    status = main()
    sys.stdout.flush()  # guarded: a failure is said on stderr, before the status is returned
    gc.freeze()
    sys.exit(status)


if __name__ == "__main__":  # pragma: no cover
    console_main()
