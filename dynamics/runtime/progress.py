"""Progress lines: one line for each step of a run that takes seconds (a pass over files, a candidate round).

Library code reports a step with :func:`step` (a context manager) or :func:`report`; the lines go to the
``robot_oed.progress`` logger, which prints nothing until a program shows it: the ``oed`` command line writes
them on stderr (never into its JSON outputs), unless ``--quiet`` (:func:`show_progress`)::

    with step("sums pass over 3 files"):
        ...                      # "oed diagnose: sums pass over 3 files: 12.3 s" when it took 2 s or more

A warning known early (about the input files, :mod:`estimation.data.input_findings`) is also said at once with
:func:`report_warning` (``oed diagnose: warning: …``); :func:`show_progress` yields the :class:`Shown` lines, so
that the end of the run does not say them again (:meth:`Shown.unsaid`).
"""

from __future__ import annotations

import contextlib
import logging
import sys
import time
from collections.abc import Iterable, Iterator
from typing import TextIO

__all__ = ["LOGGER_NAME", "SECONDS", "Shown", "report", "report_warning", "show_progress", "step"]

#: the logger the lines go to
LOGGER_NAME = "robot_oed.progress"
#: a step shorter than this says nothing
SECONDS = 2.0

_LOGGER = logging.getLogger(LOGGER_NAME)


def report(message: str, *arguments: object) -> None:
    """One progress line (``%``-style ``arguments``, formatted only when shown)."""
    _LOGGER.info(message, *arguments)


def report_warning(message: str) -> None:
    """A warning said at once as a progress line (``warning: message``); the caller also issues it as a warning."""
    _LOGGER.info("%s", message, extra={"oed_warning": True})


@contextlib.contextmanager
def step(what: str, *, seconds: float | None = None) -> Iterator[None]:
    """Report ``what`` and the time it took when it took ``seconds`` (default :data:`SECONDS`) or more."""
    started = time.perf_counter()
    yield
    elapsed = time.perf_counter() - started
    if elapsed >= (SECONDS if seconds is None else seconds):
        report("%s: %.1f s", what, elapsed)


class Shown(logging.Handler):
    """The handler of :func:`show_progress`: writes each line as ``prefix: line`` (``prefix: warning: line`` for a
    :func:`report_warning`) and keeps the warnings it wrote."""

    def __init__(self, prefix: str, stream: TextIO | None) -> None:
        super().__init__()
        self.prefix = prefix
        self.stream = stream
        self.warnings: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        message = record.getMessage()
        warning = getattr(record, "oed_warning", False)
        if warning:
            self.warnings.append(message)
        stream = sys.stderr if self.stream is None else self.stream
        stream.write(f"{self.prefix}: {'warning: ' if warning else ''}{message}\n")
        stream.flush()

    def unsaid(self, messages: Iterable[str]) -> list[str]:
        """The ``messages`` not already written as warnings."""
        said = set(self.warnings)
        return [message for message in messages if message not in said]


@contextlib.contextmanager
def show_progress(prefix: str, *, quiet: bool = False, stream: TextIO | None = None) -> Iterator[Shown]:
    """Within the block, progress lines are written to ``stream`` (default stderr) as ``prefix: line``;
    nothing with ``quiet``. Yields the :class:`Shown` handler (with ``quiet`` one that has said nothing)."""
    handler = Shown(prefix, stream)
    if quiet:
        yield handler
        return
    previous = _LOGGER.level, _LOGGER.propagate
    _LOGGER.addHandler(handler)
    _LOGGER.setLevel(logging.INFO)
    _LOGGER.propagate = False
    try:
        yield handler
    finally:
        _LOGGER.removeHandler(handler)
        _LOGGER.setLevel(previous[0])
        _LOGGER.propagate = previous[1]
