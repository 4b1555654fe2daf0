"""Deprecated path of :mod:`estimation.preprocessing.plan` (release 0.1 showed ``from estimation.preprocessing_plan import …``).

Kept for one release so that code written against that README keeps working; importing it warns. Import from
:mod:`estimation.preprocessing.plan` instead. See docs/migration.md.
"""

import warnings

from estimation.preprocessing.plan import choose_preprocessing, prepare

__all__ = ['choose_preprocessing', 'prepare']

warnings.warn(
    "estimation.preprocessing_plan is deprecated and will be removed in the next release; import from estimation.preprocessing.plan",
    DeprecationWarning,
    stacklevel=2,
)
