"""Option types checked by argparse, so that an error names the option the user typed."""

from __future__ import annotations

import argparse

from oed.workflows.design import IPOPT_ALONE


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
