"""Command-line interface: ``pmaccuracy <command> ...``.

Each command lives in its own module with a ``register(subparsers)`` function.
Every :class:`~pmaccuracy.errors.PmAccuracyError` (bad files, poses outside the
joint ranges, singular poses, negative clearances, ...) and every argument
error ends the program with exit status 2 and one line on stderr.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from ..errors import PmAccuracyError

#: Modules of ``pmaccuracy.cli`` that register commands, in help order.
COMMAND_MODULES = ("kinematics_cmd", "workspace_cmd", "bounds_cmd", "map_cmd", "reproduce_cmd",
                   "experiment_cmd", "vision_cmd")


class OneLineParser(argparse.ArgumentParser):
    """argparse, but an argument error is a single line ``pmaccuracy CMD: error: ...`` and exit 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__

    parser = OneLineParser(
        prog="pmaccuracy",
        description="Accuracy of planar 3-PPR parallel manipulators with joint clearances: kinematics, workspace, "
                    "exact worst-case pose errors, error maps, experiments and vision measurement. Lengths in mm, "
                    "angles in degrees on the command line.")
    parser.add_argument("--version", action="version", version=f"pmaccuracy {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=OneLineParser)
    sub.required = True
    for name in COMMAND_MODULES:
        importlib.import_module(f".{name}", __name__).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``pmaccuracy`` console script; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except PmAccuracyError as exc:
        print(f"pmaccuracy {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into e.g. `head`: not an error of ours
        sys.stderr.close()
        return 0
    except OSError as exc:
        print(f"pmaccuracy {args.command}: error: {exc.filename or ''}: {exc.strerror or exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
