"""Option values checked before any work, so that an error names the option the user typed
(the library's messages name its parameters: ``frequency_hz``, ``cutoff_hz``)."""

from __future__ import annotations

import argparse
import math


def check_hertz(args: argparse.Namespace, *options: str) -> None:
    """Refuse an ``options`` value (``"frequency"``, ``"cutoff"``) that is given and not a positive,
    finite number of hertz, naming the option as typed (``--frequency``)."""
    for option in options:
        value = getattr(args, option, None)
        if value is not None and not (math.isfinite(value) and value > 0):
            raise ValueError(f"--{option.replace('_', '-')} must be a positive, finite number of hertz, got {value:g}")
