"""Memory guards: refuse an allocation sized by a user's number before making it.

A count given on the command line (constraint points, cost samples, simulated samples, an APRBS
length, a streaming chunk) decides the size of arrays allocated later. Past the machine's memory
the process is swapped to a crawl or killed (``oed design --constraint-points 1000000000`` reached
22.5 GiB and exited 0). :func:`check_allocation` estimates the bytes first and raises
:class:`InsufficientMemoryError` — a ``MemoryError`` and a ``ValueError``, so the CLI reports it as
bad input (exit 2) — naming what was asked for and how much the machine has.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["InsufficientMemoryError", "available_memory", "check_allocation", "total_memory"]

#: assumed when neither /proc/meminfo nor os.sysconf says (a small machine)
FALLBACK_BYTES = 4 * 1024**3
#: share of the available memory one request may take
SHARE = 0.8


class InsufficientMemoryError(MemoryError, ValueError):
    """A request would need more memory than the machine has (estimated before allocating)."""


def _meminfo(key: str) -> int | None:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith(key + ":"):
                return int(line.split()[1]) * 1024  # kB
    except (OSError, ValueError, IndexError):
        return None
    return None


def total_memory() -> int:
    """Physical memory, bytes (``MemTotal``, else ``os.sysconf``, else :data:`FALLBACK_BYTES`)."""
    value = _meminfo("MemTotal")
    if value is None:
        try:
            value = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        except (ValueError, OSError, AttributeError):
            value = None
    return int(value) if value and value > 0 else FALLBACK_BYTES


#: a container's memory limit and use: cgroup v2, then v1 (``/proc/meminfo`` shows the host's)
CGROUP_FILES: tuple[tuple[str, str], ...] = (
    ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
    ("/sys/fs/cgroup/memory/memory.limit_in_bytes", "/sys/fs/cgroup/memory/memory.usage_in_bytes"),
)


def _cgroup_room() -> int | None:
    """Bytes left under this process's cgroup memory limit, or ``None`` without a limit."""
    for limit_file, usage_file in CGROUP_FILES:
        try:
            limit_text = Path(limit_file).read_text().strip()
            usage = int(Path(usage_file).read_text().strip())
        except (OSError, ValueError):
            continue
        if limit_text == "max" or not limit_text.isdigit() or int(limit_text) >= 2**60:
            return None  # no limit set
        return max(int(limit_text) - usage, 0)
    return None


def available_memory() -> int:
    """Memory a new allocation may take now, bytes: ``MemAvailable`` (free plus reclaimable cache),
    else ``os.sysconf`` available pages, else the total; within a container's cgroup limit."""
    value = _meminfo("MemAvailable")
    if value is None:
        try:
            value = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_AVPHYS_PAGES")
        except (ValueError, OSError, AttributeError):
            value = None
    value = int(value) if value and value > 0 else total_memory()
    room = _cgroup_room()
    return value if room is None else min(value, room)


def _size(count: float) -> str:
    for unit, scale in (("GiB", 1024**3), ("MiB", 1024**2), ("KiB", 1024)):
        if count >= scale:
            return f"{count / scale:.3g} {unit}"
    return f"{count:.0f} bytes"


def check_allocation(n_bytes: float, what: str, *, limit: int | None = None) -> None:
    """Raise :class:`InsufficientMemoryError` if ``n_bytes`` exceed :data:`SHARE` of the available
    memory (or of ``limit`` bytes when given).

    Parameters
    ----------
    n_bytes
        Estimated size of the allocation (a float, so that an absurd count does not overflow).
    what
        What asked for it, for the message (``"--constraint-points 1000000000"``).
    """
    budget = SHARE * (available_memory() if limit is None else limit)
    if not n_bytes <= budget:  # also NaN
        raise InsufficientMemoryError(
            f"{what} needs about {_size(float(n_bytes))}, more than this machine can give "
            f"({_size(budget)} of {_size(total_memory())}): reduce it"
        )
