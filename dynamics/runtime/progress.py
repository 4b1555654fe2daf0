"""Progress lines: one line for each step of a run that takes seconds (a pass over files, a candidate round).

Library code reports a step with :func:`step` (a context manager) or :func:`report`; the lines go to the
``robot_oed.progress`` logger, which prints nothing until a program shows it: the ``oed`` command line writes
them on stderr (never into its JSON outputs), unless ``--quiet`` (:func:`show_progress`)::

    with step("sums pass over 3 files"):
        ...                      # "oed diagnose: sums pass over 3 files: running (over 2 s)" once it has run 2 s,
                                 # "oed diagnose: sums pass over 3 files: 12.3 s" when it ends

A step that runs longer than :data:`SECONDS` says so while it runs (a watcher thread waits for its end that long,
and only while a program shows the lines); its end line says how long it took.

A warning known early (about the input files, :mod:`estimation.data.input_findings`) is also said at once with
:func:`report_warning` (``oed diagnose: warning: …``); :func:`show_progress` yields the :class:`Shown` lines, so
that the end of the run does not say them again (:meth:`Shown.unsaid`).
"""

from __future__ import annotations

import contextlib
import logging
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
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
def step(what: str, *, seconds: float | None = None, clock: Callable[[], float] = time.perf_counter,
         wait: Callable[[threading.Event, float], bool] | None = None) -> Iterator[None]:
    """Report ``what`` while it runs once it has run ``seconds`` (default :data:`SECONDS`): ``what: running (over
    2 s)``, and at its end the time it took when it took that long or longer.

    Parameters
    ----------
    what
        The step, in a few words.
    seconds
        How long a step runs before it is said (default :data:`SECONDS`).
    clock
        The clock the time taken is read on (for tests: a fake one).
    wait
        ``wait(done, seconds)``: waits for the step's end (``done`` set) at most ``seconds``; ``True`` when it
        ended. Default ``done.wait(seconds)`` in a watcher thread; a test passes one that returns at once.
    """
    limit = SECONDS if seconds is None else seconds
    started = clock()
    done = threading.Event()
    watcher = None
    if _LOGGER.isEnabledFor(logging.INFO) and _LOGGER.hasHandlers():  # a program shows the lines: watch the step
        watcher = threading.Thread(target=_say_running, args=(what, limit, done, wait or _wait), daemon=True,
                                   name=f"progress: {what}")
        watcher.start()
    try:
        yield
    finally:
        done.set()
        if watcher is not None:
            watcher.join()
    elapsed = clock() - started
    if elapsed >= limit:
        report("%s: %.1f s", what, elapsed)


def _wait(done: threading.Event, seconds: float) -> bool:
    return done.wait(seconds)


def _say_running(what: str, seconds: float, done: threading.Event,
                 wait: Callable[[threading.Event, float], bool]) -> None:
    """The watcher of :func:`step`: says the step once it has run ``seconds`` without ending."""
    if not wait(done, seconds):
        report("%s: running (over %.3g s)", what, seconds)


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
