"""The filter that drops distributed's known Ctrl-C race (its cancel callback reads an unbound ``future``) drops
that record alone: any other NameError, or the same error raised elsewhere, still reaches the log."""
from __future__ import annotations

import logging
import sys

from bitemesh.cohorts.run import CancelRaceFilter


def record_of(function_name: str, filename: str) -> logging.LogRecord:
    """The record tornado logs for a callback ``function_name``, defined in ``filename``, that reads an unbound
    name."""
    namespace = {}
    exec(compile(f"def {function_name}():\n    return unbound\n", filename, "exec"), namespace)
    try:
        namespace[function_name]()
    except NameError:
        exc_info = sys.exc_info()
    return logging.LogRecord("tornado.application", logging.ERROR, filename, 1, "Exception in callback",
                             None, exc_info)


def test_the_race_in_distributed_is_dropped():
    assert not CancelRaceFilter().filter(record_of("cancel", "/site-packages/distributed/utils.py"))


def test_other_errors_pass():
    race = CancelRaceFilter()
    assert race.filter(record_of("cancel", "/site-packages/bitemesh/cohorts/run.py"))
    assert race.filter(record_of("wait", "/site-packages/distributed/utils.py"))
    assert race.filter(logging.LogRecord("tornado.application", logging.ERROR, "x", 1, "plain", None, None))
