"""The measured-data container now lives in :mod:`dynamics.measurements` (the simulator records
it; layers point down). Re-exported here so that every existing import keeps working.
"""

from dynamics.measurements import (  # noqa: F401
    joint_columns,
    _real_array,
    Measurements,
)

__all__ = ["joint_columns", "Measurements"]
