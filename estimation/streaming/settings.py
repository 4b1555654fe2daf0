"""The streamed path's settings that the verbs' options and the command line name as their defaults, and the
scheduler a run is given (whether it streams): importing them imports none of the streamed path's modules (a run
that stays in memory never imports them)."""

from __future__ import annotations

import os

__all__ = ["DEFAULT_SUBSAMPLE", "FLOOR_WINDOW", "SCHEDULER_VARIABLE", "scheduler_address"]

#: samples (about; at most twice) of the evenly spread training subsample the shapes are searched on.
#: The shape search costs what the in-memory diagnosis's first round costs on that many samples.
DEFAULT_SUBSAMPLE = 10_000

#: the first rows of each validation file the streamed diagnosis took its noise floor on until every row became the
#: default (h-streamfloor); a value for ``--floor-window N`` where reading every row costs too much
FLOOR_WINDOW = 100_000

#: environment variable holding a dask scheduler's address (``tcp://host:8786``)
SCHEDULER_VARIABLE = "ROBOT_OED_SCHEDULER"


def scheduler_address(given: str | None) -> str | None:
    """The scheduler to use: ``given``, else ``$ROBOT_OED_SCHEDULER``, else ``None`` (no cluster)."""
    address = given if given is not None else os.environ.get(SCHEDULER_VARIABLE)
    return address.strip() or None if address is not None else None
