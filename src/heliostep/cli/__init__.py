"""The ``heliostep`` command line: argument parsing and exit codes only.

Each command lives in its own module of this package, which exposes ``register(subparsers)``; that
function adds the command's parser and sets ``func`` (taking the parsed arguments and
returning an exit status). This module only assembles them and turns a
:class:`~heliostep.errors.HeliostepError` into one line on stderr: exit status 1 for a
:class:`~heliostep.errors.RunFailure` (a build, an FMU or the solver failed), 2 for any other (bad
input); a KeyboardInterrupt that reaches it becomes one line and exit status 130.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from heliostep._version import __version__
from heliostep.cli.signals import ForcedStop
from heliostep.errors import HeliostepError, RunFailure

#: Modules that provide a command, in the order ``--help`` lists them.
COMMAND_MODULES = (
    "heliostep.cli.build",
    "heliostep.cli.geometry",
    "heliostep.cli.endloss",
    "heliostep.cli.run",
    "heliostep.cli.compare",
    "heliostep.cli.regress",
    "heliostep.cli.sweep",
    "heliostep.cli.fieldlight",
)


def make_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="heliostep",
        description="Co-simulate the stepper drives of solar-tracking mirrors.",
    )
    parser.add_argument("--version", action="version", version=f"heliostep {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = make_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except HeliostepError as exc:
        print(f"heliostep {args.command}: error: {exc}", file=sys.stderr)
        return 1 if isinstance(exc, RunFailure) else 2
    except KeyboardInterrupt:
        print(f"heliostep {args.command}: interrupted", file=sys.stderr)
        return 130
    except ForcedStop as forced:  # a second SIGINT/SIGTERM: left at once, temporary files removed
        print(
            f"heliostep {args.command}: stopped by {forced}: exited without finishing the clean-up "
            f"(no file was left claiming to be complete)",
            file=sys.stderr,
        )
        return forced.exit_status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
