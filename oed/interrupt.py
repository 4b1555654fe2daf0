"""Ctrl-C during a CasADi solve: noted here, because CasADi turns it into a solver status.

CasADi checks for signals while IPOPT runs and, on SIGINT, ends the solve with the status
``NonIpopt_Exception_Thrown``; the multi-start design would then go on with the next start and
write its results. :func:`interrupt_flag` records the signal so that the caller can raise
``KeyboardInterrupt`` after the solve returns.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from typing import Any


@contextlib.contextmanager
def interrupt_flag() -> Iterator[Callable[[], bool]]:
    """Note a Ctrl-C (SIGINT) that arrives during the block, which CasADi would otherwise swallow
    into the solver status ``NonIpopt_Exception_Thrown``. Only the main thread receives signals;
    elsewhere (thread pools) nothing is installed."""
    if threading.current_thread() is not threading.main_thread():
        yield lambda: False
        return
    received: list[int] = []
    previous = signal.getsignal(signal.SIGINT)

    def note(signum: int, frame: Any) -> None:
        received.append(signum)
        raise KeyboardInterrupt

    signal.signal(signal.SIGINT, note)
    try:
        yield lambda: bool(received)
    finally:
        signal.signal(signal.SIGINT, previous)
