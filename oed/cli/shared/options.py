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


#: ``--sqp-after none``: IPOPT alone (the option's absence is ``None``: the verb's default)
IPOPT_ALONE = "none"


def sqp_after(text: str) -> int | str:
    """``--sqp-after``: a non-negative integer or ``none`` (argparse type)."""
    if text.strip().lower() == IPOPT_ALONE:
        return IPOPT_ALONE
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer or none, got {text!r}")
    return value


def handover(args: argparse.Namespace, default: int | None) -> int | None:
    """``DesignSettings.sqp_after`` from ``--sqp-after``: ``default`` when not given, ``None`` for ``none``."""
    if args.sqp_after is None:
        return default
    return None if args.sqp_after == IPOPT_ALONE else args.sqp_after
