"""The diagnosis's candidates: fitting every candidate effect against the current model, effects on joint
combinations (coupled joints, motors), and the delay between torques and motion as a candidate.

Modules: :mod:`~estimation.diagnosis.candidates.coupling`, :mod:`~estimation.diagnosis.candidates.delay`,
:mod:`~estimation.diagnosis.candidates.delay_search`, :mod:`~estimation.diagnosis.candidates.projected_columns`,
:mod:`~estimation.diagnosis.candidates.trials`.
"""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "DelayComparison": "estimation.diagnosis.candidates.delay",
    "DelaySearch": "estimation.diagnosis.candidates.delay_search",
    "DelayTrial": "estimation.diagnosis.candidates.delay",
    "Regressor": "estimation.diagnosis.candidates.delay",
    "SIGNIFICANT_TERM": "estimation.diagnosis.candidates.trials",
    "Trial": "estimation.diagnosis.candidates.trials",
    "candidate_label": "estimation.diagnosis.candidates.trials",
    "combination_groups": "estimation.diagnosis.candidates.coupling",
    "combination_taken": "estimation.diagnosis.candidates.coupling",
    "coupling_candidates": "estimation.diagnosis.candidates.coupling",
    "fit_or_reason": "estimation.diagnosis.candidates.trials",
    "joints_of": "estimation.diagnosis.candidates.trials",
    "nested_test": "estimation.diagnosis.candidates.trials",
    "pair_tests": "estimation.diagnosis.candidates.coupling",
    "per_joint_extra": "estimation.diagnosis.candidates.coupling",
    "search_delay": "estimation.diagnosis.candidates.delay",
    "traced_pairs": "estimation.diagnosis.candidates.coupling",
    "weighted_error": "estimation.diagnosis.candidates.trials",
    "with_delay": "estimation.diagnosis.candidates.delay_search",
    "wrong_sign": "estimation.diagnosis.candidates.trials",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
