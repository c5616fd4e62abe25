"""Command-line options generated from the parameter dataclasses, and the progress bar."""
from __future__ import annotations

import sys
import time
from dataclasses import fields

from ..core.fem.coordinates import COORDINATE_ARRAYS
from ..core.fem.fibres import FIBRE_ARRAYS, LAPLACE_ARRAYS, FibreParameters
from ..core.mesh.quality import quality_summary
from ..core.parameters import AUTOMATIC, STEP_PARAMETERS, is_optional
from ..meshing import write
from ..options import Options
from . import cancel_requested


def describe(metadata: dict, default) -> str:
    """Help text of one parameter: what it is, its unit, range and default."""
    text = metadata["help"]
    if metadata.get("unit"):
        text += f" [{metadata['unit']}]"
    if "range" in metadata:
        low, high, low_open, high_open = metadata["range"]
        text += f"; range {'(' if low_open else '['}{'-inf' if low is None else low}, " \
                f"{'inf' if high is None else high}{')' if high_open else ']'}"
    text += f"; default {default}" if default not in (None, "") else ""
    return text.replace("%", "%%")   # argparse formats help texts with %


def add_parameter_options(parser, parameter_classes=STEP_PARAMETERS) -> None:
    """One ``--flag-name`` per field of each parameter dataclass, typed and described from its metadata."""
    for cls in parameter_classes:
        group = parser.add_argument_group(cls.__doc__.split(":")[0])
        for item in fields(cls):
            flag = f"--{item.name.replace('_', '-')}"
            if is_switch(item):   # a 0/1 parameter: --name sets it to 1, --no-name to 0
                on, _, off = item.metadata["help"].removeprefix("1 ").partition("; 0 ")
                off = off or f"the opposite of {flag}"
                marks = ("", " (the default)") if item.default else (" (the default)", "")
                group.add_argument(flag, dest=item.name, action="store_const", const=1, default=item.default,
                                   help=(on + marks[1]).replace("%", "%%"))
                group.add_argument(f"--no-{flag[2:]}", dest=item.name, action="store_const", const=0,
                                   help=(off + marks[0]).replace("%", "%%"))
                continue
            text = "choices" in item.metadata or "text" in item.metadata
            kind = str if text else int if item.metadata["integer"] else float
            help = describe(item.metadata, item.default)
            if is_optional(item):
                kind, help = or_automatic(kind), f"{help}; {AUTOMATIC} or auto: automatic (the default)"
            group.add_argument(flag, dest=item.name, type=kind, choices=item.metadata.get("choices"),
                               default=item.default, help=help)


def add_threads_option(parser) -> None:
    """``--threads N``: the threads of the parallel kernels (the Options field, with its help)."""
    threads = {item.name: item for item in fields(Options)}["threads"]
    parser.add_argument("--threads", type=int, metavar="N", help=describe(threads.metadata, None))


def add_fibre_options(parser) -> None:
    """``--fibres`` and the angles of the rule (FibreParameters)."""
    add_parameter_options(parser, (FibreParameters,))


def or_automatic(kind):
    """An argparse type: a number of ``kind``, or None for "auto" and :data:`AUTOMATIC` (-1), as in every
    interface."""
    def parse(text: str):
        if text.strip().lower() == "auto":
            return None
        number = kind(text)
        return None if number == AUTOMATIC else number
    parse.__name__ = kind.__name__   # argparse names the type in its "invalid float value" message
    return parse


def is_switch(item) -> bool:
    """True for a parameter that is an integer 0 or 1."""
    return item.metadata.get("integer") and item.metadata.get("range", ())[:2] == (0, 1)


def parameters_from_args(args, parameter_classes=STEP_PARAMETERS) -> list:
    """The parameter dataclasses filled from parsed options (each checks its ranges)."""
    return [cls(**{item.name: getattr(args, item.name) for item in fields(cls)}) for cls in parameter_classes]


class ProgressBar:
    """A one-line progress bar on stderr, shown once a run has taken more than ``delay`` seconds."""

    #: the bar whose line the cursor is at the end of: a note printed now ends that line first (:meth:`end_line`)
    drawing = None

    def __init__(self, stream=None, delay: float = 1.0, width: int = 30):
        # sys.stderr looked up now, not at import: redirections made after import (tests, callers) apply.
        self.stream = sys.stderr if stream is None else stream
        self.delay, self.width = delay, width
        self.start = time.perf_counter()
        self.shown = False
        self.last = None
        self.length = 0  # characters of the line last drawn

    def __call__(self, fraction: float, message: str = "") -> None:
        if cancel_requested():   # a Ctrl-C whose KeyboardInterrupt was swallowed on its way (see there)
            raise KeyboardInterrupt
        if not self.shown and time.perf_counter() - self.start < self.delay:
            return
        self.shown = True
        filled = int(round(fraction * self.width))
        if (filled, message) == self.last:
            return
        self.last = (filled, message)
        line = f"[{'#' * filled}{' ' * (self.width - filled)}] {fraction:4.0%} {message:<24}"
        # Pad to the previous line's length: a shorter message must not leave the end of a longer one behind.
        self.stream.write(f"\r{line:<{self.length}}")
        self.length = len(line)
        self.stream.flush()
        ProgressBar.drawing = self

    @classmethod
    def end_line(cls) -> None:
        """End the line a bar is drawing, so that what is printed next starts a line of its own (the bar goes on
        below it)."""
        bar, cls.drawing = cls.drawing, None
        if bar is not None:
            bar.stream.write("\n")
            bar.stream.flush()
            bar.length, bar.last = 0, None

    def close(self) -> None:
        if ProgressBar.drawing is self:
            ProgressBar.end_line()


def write_and_report(result, output, note: str = "") -> None:
    """Write the mesh of a pipeline result, then print R, the quality summary, the fidelity and the time per
    step."""
    write(result, output)
    print(f"wrote {output} (radius R = {result.radius:.4g}{note})")
    if "fibres" in result.seconds:
        print(f"fibres: cell arrays {', '.join(FIBRE_ARRAYS)} (Bayer et al. 2012); point arrays "
              f"{', '.join(LAPLACE_ARRAYS)} (its Laplace solutions)")
    if "coordinates" in result.seconds:
        print(f"coordinates: point arrays {', '.join(COORDINATE_ARRAYS + LAPLACE_ARRAYS)}; cell arrays AHA, "
              "Ventricle")
    print(quality_summary(result.mesh))
    if result.fidelity is not None:
        print(f"fidelity: {result.fidelity.describe()}")
    print("time per step:")
    print_timings(result.seconds)


def print_timings(seconds: dict, stream=None) -> None:
    """Seconds per step, and their total (on ``stream``, default the current sys.stdout)."""
    stream = sys.stdout if stream is None else stream
    width = max(map(len, seconds))
    for name, value in seconds.items():
        print(f"  {name:<{width}}  {value:7.2f} s", file=stream)
    print(f"  {'total':<{width}}  {sum(seconds.values()):7.2f} s", file=stream)
