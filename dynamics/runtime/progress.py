"""Progress lines: one line for each step of a run that takes seconds (a pass over files, a candidate round).

Library code reports a step with :func:`step` (a context manager) or :func:`report`; the lines go to the
``robot_oed.progress`` logger, which prints nothing until a program shows it: the ``oed`` command line writes
them on stderr (never into its JSON outputs), unless ``--quiet`` (:func:`show_progress`)::

    with step("sums pass over 3 files"):
        ...                      # "oed diagnose: sums pass over 3 files: 12.3 s" when it took 2 s or more
"""

from __future__ import annotations

import contextlib
import logging
import sys
import time
from collections.abc import Iterator
from typing import TextIO

__all__ = ["LOGGER_NAME", "SECONDS", "report", "show_progress", "step"]

#: the logger the lines go to
LOGGER_NAME = "robot_oed.progress"
#: a step shorter than this says nothing
SECONDS = 2.0

_LOGGER = logging.getLogger(LOGGER_NAME)


def report(message: str, *arguments: object) -> None:
    """One progress line (``%``-style ``arguments``, formatted only when shown)."""
    _LOGGER.info(message, *arguments)


@contextlib.contextmanager
def step(what: str, *, seconds: float = SECONDS) -> Iterator[None]:
    """Report ``what`` and the time it took when it took ``seconds`` or more."""
    started = time.perf_counter()
    yield
    elapsed = time.perf_counter() - started
    if elapsed >= seconds:
        report("%s: %.1f s", what, elapsed)


@contextlib.contextmanager
def show_progress(prefix: str, *, quiet: bool = False, stream: TextIO | None = None) -> Iterator[None]:
    """Within the block, progress lines are written to ``stream`` (default stderr) as ``prefix: line``;
    nothing with ``quiet``."""
    if quiet:
        yield
        return
    handler = logging.StreamHandler(sys.stderr if stream is None else stream)
    handler.setFormatter(logging.Formatter(f"{prefix}: %(message)s"))
    previous = _LOGGER.level, _LOGGER.propagate
    _LOGGER.addHandler(handler)
    _LOGGER.setLevel(logging.INFO)
    _LOGGER.propagate = False
    try:
        yield
    finally:
        _LOGGER.removeHandler(handler)
        _LOGGER.setLevel(previous[0])
        _LOGGER.propagate = previous[1]
