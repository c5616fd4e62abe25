"""The ``bitemesh`` command: one module per subcommand (mesh, quality, demo)."""
from __future__ import annotations

import argparse
import sys

from .. import __version__
from ..core.errors import BitemeshError, Cancelled
from . import demo, mesh, quality

COMMANDS = (mesh, quality, demo)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="bitemesh", description="Tetrahedral meshes from scattered points "
                                     "(implicit surface, biting node placement, Delaunay).")
    parser.add_argument("--version", action="version", version=f"bitemesh {__version__}")
    subcommands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in COMMANDS:
        command.add_parser(subcommands)
    return parser


def main(argv=None) -> int:
    """Run the command line; return the exit code (0 done, 1 bad input or failure, 2 usage, 130 interrupted)."""
    args = build_parser().parse_args(argv)
    try:
        args.run(args)
    except (Cancelled, KeyboardInterrupt):
        print("\nbitemesh: cancelled", file=sys.stderr)
        return 130
    except BitemeshError as error:
        print(f"bitemesh: error: {error}", file=sys.stderr)
        return 1
    return 0
