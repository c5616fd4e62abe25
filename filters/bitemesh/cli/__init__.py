"""The ``bitemesh`` command: one module per subcommand (mesh, quality, demo)."""
from __future__ import annotations

import argparse
import os
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
    """Run the command line; return the exit code (0 done, 1 bad input or failure, 2 usage, 130 interrupted,
    141 output pipe closed)."""
    args = build_parser().parse_args(argv)
    try:
        args.run(args)
        sys.stdout.flush()  # here, not at exit, so that a closed pipe is caught below
    except BrokenPipeError:
        # Whoever read our output stopped (bitemesh quality m.vtu | head -1): stop quietly, as a shell tool does.
        # Point stdout at /dev/null so that the flush at interpreter exit does not fail again.
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError):  # stdout is not a file descriptor (captured, redirected in Python)
            pass
        return 141
    except (Cancelled, KeyboardInterrupt):
        print("\nbitemesh: cancelled", file=sys.stderr)
        return 130
    except BitemeshError as error:
        print(f"bitemesh: error: {error}", file=sys.stderr)
        return 1
    return 0
