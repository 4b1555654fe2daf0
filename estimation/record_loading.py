"""Deprecated path of :mod:`estimation.data.records` (release 0.1 showed ``from estimation.record_loading import …``).

Kept for one release so that code written against that README keeps working; importing it warns. Import from
:mod:`estimation.data.records` instead. See docs/migration.md.
"""

import warnings

from estimation.data.records import read_record

__all__ = ['read_record']

warnings.warn(
    "estimation.record_loading is deprecated and will be removed in the next release; import from estimation.data.records",
    DeprecationWarning,
    stacklevel=2,
)
