"""Close the loop on measured data: the search for what a model lacks, its candidates, rules and confirmation, the final refit, the results and their report.

Modules: :mod:`~estimation.diagnosis.candidates.trials`, :mod:`~estimation.diagnosis.rules.robust_test`, :mod:`~estimation.diagnosis.search_fits`, :mod:`~estimation.diagnosis.search_moves`, :mod:`~estimation.diagnosis.confirmation`, :mod:`~estimation.diagnosis.candidates.coupling`, :mod:`~estimation.diagnosis.candidates.delay`, :mod:`~estimation.diagnosis.candidates.delay_search`, :mod:`~estimation.diagnosis.final_refit`, :mod:`~estimation.diagnosis.forward_selection`, :mod:`~estimation.diagnosis.limit_laws`, :mod:`~estimation.diagnosis.record_fits`, :mod:`~estimation.diagnosis.report`, :mod:`~estimation.diagnosis.results`, :mod:`~estimation.diagnosis.search`, :mod:`~estimation.diagnosis.rules.selection_rules`, :mod:`~estimation.diagnosis.sign_constraints`, :mod:`~estimation.diagnosis.statistics`, :mod:`~estimation.diagnosis.rules.stopping_rules`, :mod:`~estimation.diagnosis.traced_refinement`.
"""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "AdoptedEffect": "estimation.diagnosis.search_fits",
    "ChannelErrors": "estimation.identification.validation",
    "Alternative": "estimation.diagnosis.runner_up",
    "CandidateComparison": "estimation.diagnosis.confirmation",
    "Diagnosis": "estimation.diagnosis.results",
    "DiagnosisSearch": "estimation.diagnosis.forward_selection",
    "FLOOR_ALPHA": "estimation.diagnosis.statistics",
    "FoundEffect": "estimation.diagnosis.results",
    "LastMove": "estimation.diagnosis.runner_up",
    "NOTHING_TRIED": "estimation.diagnosis.runner_up",
    "REWEIGHTING_PASSES": "estimation.diagnosis.confirmation",
    "RejectedEffect": "estimation.diagnosis.results",
    "ResidualReport": "estimation.diagnosis.statistics",
    "RivalAhead": "estimation.diagnosis.runner_up",
    "RivalFit": "estimation.diagnosis.runner_up",
    "RivalFitter": "estimation.diagnosis.runner_up",
    "RunnerUp": "estimation.diagnosis.results",
    "RunnerUpOutcome": "estimation.diagnosis.runner_up",
    "RunnerUpSearch": "estimation.diagnosis.runner_up",
    "SearchOutcome": "estimation.diagnosis.forward_selection",
    "SearchSettings": "estimation.diagnosis.forward_selection",
    "SummedFit": "estimation.diagnosis.results",
    "TrialRequest": "estimation.diagnosis.search_fits",
    "TrialTest": "estimation.diagnosis.search_fits",
    "UntouchedErrors": "estimation.diagnosis.untouched",
    "bic_gap": "estimation.diagnosis.runner_up",
    "candidate_blocks": "estimation.diagnosis.forward_selection",
    "candidate_columns": "estimation.diagnosis.search",
    "declared_friction_joints": "estimation.diagnosis.forward_selection",
    "default_candidates": "estimation.diagnosis.search",
    "diagnose": "estimation.diagnosis.search",
    "effect_channels": "estimation.diagnosis.search",
    "fit_runner_up": "estimation.diagnosis.runner_up",
    "floor_for_validation": "estimation.diagnosis.statistics",
    "in_memory_fitter": "estimation.diagnosis.runner_up",
    "limit_law": "estimation.diagnosis.limit_laws",
    "markdown_report": "estimation.diagnosis.report",
    "negative_terms": "estimation.diagnosis.sign_constraints",
    "pin_wrong_signs": "estimation.diagnosis.sign_constraints",
    "plot_residuals": "estimation.diagnosis.report",
    "plot_trace": "estimation.diagnosis.report",
    "recorded_mse": "estimation.diagnosis.untouched",
    "replace_limit_laws": "estimation.diagnosis.limit_laws",
    "residual_report": "estimation.diagnosis.statistics",
    "residual_statistics": "estimation.diagnosis.search",
    "runner_up_line": "estimation.diagnosis.results",
    "settled_weights": "estimation.diagnosis.confirmation",
    "untouched_errors": "estimation.diagnosis.untouched",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
