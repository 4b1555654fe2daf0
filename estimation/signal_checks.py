"""The servo workflow's input checks now live in :mod:`dynamics.signal_checks` (the servo simulator
checks its inputs with them; layers point down). Re-exported here so that existing imports keep working.
"""

from dynamics.signal_checks import (  # noqa: F401
    single_channel,
    check_informative,
    rank_deficiency_message,
    check_uniform_time,
    check_in_ranges,
)

__all__ = ["single_channel", "check_informative", "rank_deficiency_message", "check_uniform_time", "check_in_ranges"]
