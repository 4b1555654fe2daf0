"""Deprecated path of :mod:`estimation.uncertainty.noise_floor` (release 0.1 showed ``from estimation.noise_floor import …``).

Kept for one release so that code written against that README keeps working; importing it warns. Import from
:mod:`estimation.uncertainty.noise_floor` instead. See docs/migration.md.
"""

import warnings

from estimation.uncertainty.noise_floor import noise_floor
from estimation.uncertainty.floor_comparison import above_floor

__all__ = ['above_floor', 'noise_floor']

warnings.warn(
    "estimation.noise_floor is deprecated and will be removed in the next release; import from estimation.uncertainty.noise_floor",
    DeprecationWarning,
    stacklevel=2,
)
