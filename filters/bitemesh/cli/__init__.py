"""The ``bitemesh`` command: one module per subcommand (mesh, quality, demo).

Nothing heavy is imported before :func:`main` runs, and everything it imports runs under its Ctrl-C guard: an
interrupt at any moment ends with one line and exit code 130.  When this package starts the program (``bitemesh``,
``python -m bitemesh.cli``), its first statements hold back a Ctrl-C that arrives while it is still being imported;
main then cancels at once.  (An interrupt inside the interpreter's own start, before these lines run, is Python's:
the first 20 ms or so after launch on a quiet machine.)
"""
from __future__ import annotations

import _signal
import sys


def _starts_the_program() -> bool:
    """Whether this import is the start of ``python -m bitemesh.cli`` (argv[0] is "-m" while runpy looks for the
    module) or of the ``bitemesh`` console script, rather than a library's import."""
    if sys.argv[:1] == ["-m"]:
        return "bitemesh.cli" in getattr(sys, "orig_argv", ())
    script = sys.argv[0].replace("\\", "/").rsplit("/", 1)[-1] if sys.argv else ""
    return script.split(".")[0] == "bitemesh"


#: The Ctrl-C signals held back while the program's modules load (None when imported as a library).
_held_back = [] if _starts_the_program() else None
if _held_back is not None:
    _signal.signal(_signal.SIGINT, lambda number, frame: _held_back.append(number))

#: The Ctrl-C signals main's handler received (see :func:`cancel_requested`).
_cancels = []

import logging  # noqa: E402  (after the Ctrl-C hold-back above)
import os  # noqa: E402
import signal  # noqa: E402
import warnings  # noqa: E402


class _Notes(logging.Handler):
    """The "bitemesh" logger's records on stderr, one line each: ``bitemesh: note: ...``."""

    def emit(self, record):
        from .options import ProgressBar
        kind = "note" if record.levelno < logging.WARNING else "warning"
        ProgressBar.end_line()
        print(f"bitemesh: {kind}: {record.getMessage()}", file=sys.stderr)


def _show_warning(message, category, filename, lineno, file=None, line=None):
    from .options import ProgressBar
    ProgressBar.end_line()
    print(f"bitemesh: warning: {message}", file=sys.stderr)


def build_parser():
    import argparse

    from .. import __version__
    from . import batch, demo, fem, fit, mesh, quality

    parser = argparse.ArgumentParser(prog="bitemesh", description="Tetrahedral meshes from scattered points "
                                     "(implicit surface, biting node placement, Delaunay).")
    parser.add_argument("--version", action="version", version=f"bitemesh {__version__}")
    subcommands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in (mesh, fit, batch, quality, fem, demo):
        command.add_parser(subcommands)
    return parser


def main(argv=None) -> int:
    """Run the command line; return the exit code (0 done, 1 bad input or failure, 2 usage, 130 interrupted,
    141 output pipe closed)."""
    logger = logging.getLogger("bitemesh")
    handler = _Notes()
    logger.addHandler(handler)
    previous_level = logger.level
    logger.setLevel(logging.INFO)
    shown = warnings.showwarning
    warnings.showwarning = _show_warning
    try:
        if _held_back is not None:   # the program's start: Ctrl-C cancels from here on
            signal.signal(signal.SIGINT, _interrupt)
            if _held_back:
                _interrupt()
        return _run(argv)
    except BaseException as error:   # noqa: B036 (the interrupt, whatever it became on its way out, is a cancel)
        if not (cancel_requested() or _interrupted(error)):
            raise
        said = str(error) if isinstance(error, KeyboardInterrupt) else ""   # "... was written to ... first"
        print(f"\nbitemesh: cancelled{f' ({said})' if said else ''}", file=sys.stderr)
        return 130
    finally:
        logger.removeHandler(handler)
        logger.setLevel(previous_level)
        warnings.showwarning = shown


def cancel_requested() -> bool:
    """Whether the user pressed Ctrl-C in this program.  The KeyboardInterrupt may not reach main as itself: one
    raised inside a ``__del__`` is swallowed, one inside numba's compiler leaves it half done (its cache write then
    fails with "RuntimeError: no compiled object yet"); the progress bar raises it again and main treats any error
    that follows as the cancel."""
    return bool(_cancels)


def _interrupted(error: BaseException) -> bool:
    """Whether a KeyboardInterrupt caused ``error``: a Ctrl-C that lands while a compiled kernel runs Python inside
    numba's runtime (unpickling a constant) comes out of the kernel's call as "SystemError: ... returned a result
    with an exception set", the interrupt its cause."""
    while error is not None:
        if isinstance(error, KeyboardInterrupt):
            return True
        error = error.__cause__ or error.__context__
    return False


def _interrupt(number=None, frame=None):
    """The program's Ctrl-C: a KeyboardInterrupt, and from then on further Ctrl-C and the errors of ``__del__``
    methods are ignored while the program unwinds (a second Ctrl-C landing in main's cleanup printed a traceback).
    An object whose construction the interrupt cut short (numba's compiler, on a first run) may fail in its
    ``__del__`` as the interrupt unwinds; Python would print "Exception ignored ... Traceback".  The user asked to
    stop."""
    _cancels.append(number)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    sys.unraisablehook = lambda unraisable: None
    raise KeyboardInterrupt


def command() -> None:
    """The ``bitemesh`` console command: :func:`main`, then exit with its code.

    Once main has returned, the output is written or refused; from then on Ctrl-C is ignored, so that it cannot
    kill the exiting interpreter (whose finalisation restores the default handler).  After a cancel the process
    ends at once with 130: an interrupt that fell inside an import's C-level code evaluation leaves CPython set to
    kill itself with SIGINT at exit, whatever code main returned.
    """
    code = main()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if code == 130:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


def _run(argv) -> int:
    from ..core.compiled import using_threads
    from ..core.errors import BitemeshError, Cancelled

    args = build_parser().parse_args(argv)
    try:
        with using_threads(getattr(args, "threads", None)):
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
    except Cancelled:
        print("\nbitemesh: cancelled", file=sys.stderr)
        return 130
    except BitemeshError as error:
        if cancel_requested():
            raise
        print(f"bitemesh: error: {error}", file=sys.stderr)
        return 1
    return 0
