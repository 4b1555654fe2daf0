"""The diagnosis's rules: which candidates a round tries (:mod:`.selection_rules`), when the search stops
(:mod:`.stopping_rules`) and the robust test that adopts an effect (:mod:`.robust_test`)."""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "SCREEN_REFINED": "estimation.diagnosis.rules.selection_rules",
    "SearchState": "estimation.diagnosis.rules.stopping_rules",
    "WaldTest": "estimation.diagnosis.rules.robust_test",
    "candidate_groups": "estimation.diagnosis.rules.selection_rules",
    "estimate_test": "estimation.diagnosis.rules.robust_test",
    "fit_covariance": "estimation.diagnosis.rules.robust_test",
    "floor_stopping_rule": "estimation.diagnosis.rules.stopping_rules",
    "offsets_beat_springs": "estimation.diagnosis.rules.selection_rules",
    "provisional_stopping_rule": "estimation.diagnosis.rules.stopping_rules",
    "refine_best": "estimation.diagnosis.rules.selection_rules",
    "wald_test": "estimation.diagnosis.rules.robust_test",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
