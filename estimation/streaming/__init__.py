"""Long records in bounded memory: records read chunk by chunk, their time base and periods, sums over many files (clusters), and the streamed identification and diagnosis.

Modules: :mod:`~estimation.streaming.block_errors`, :mod:`~estimation.streaming.candidate_screening`, :mod:`~estimation.streaming.chunks`, :mod:`~estimation.streaming.cluster`, :mod:`~estimation.streaming.covariance`, :mod:`~estimation.streaming.cutoff_choice`, :mod:`~estimation.streaming.diagnosis`, :mod:`~estimation.streaming.diagnosis_result`, :mod:`~estimation.streaming.diagnosis_selection`, :mod:`~estimation.streaming.diagnosis_candidates`, :mod:`~estimation.streaming.diagnosis_passes`, :mod:`~estimation.streaming.diagnosis_sums`, :mod:`~estimation.streaming.identification`, :mod:`~estimation.streaming.model_selection`, :mod:`~estimation.streaming.periods`, :mod:`~estimation.streaming.recorded_errors`, :mod:`~estimation.streaming.selection`, :mod:`~estimation.streaming.settings`, :mod:`~estimation.streaming.time_base`.
"""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "BATCH_LENGTHS": "estimation.streaming.covariance",
    "BatchScores": "estimation.streaming.covariance",
    "DEFAULT_SUBSAMPLE": "estimation.streaming.settings",
    "EvenSubsample": "estimation.streaming.diagnosis_sums",
    "FLOOR_WINDOW": "estimation.streaming.settings",
    "IncompleteSumError": "estimation.streaming.cluster",
    "SCHEDULER_VARIABLE": "estimation.streaming.settings",
    "StreamingUnsupportedError": "estimation.streaming.chunks",
    "WorkerLostError": "estimation.streaming.cluster",
    "accumulate_candidates": "estimation.streaming.candidate_screening",
    "check_parts": "estimation.streaming.cluster",
    "choose_streamed_preprocessing": "estimation.streaming.cutoff_choice",
    "connect": "estimation.streaming.cluster",
    "diagnose_files": "estimation.streaming.diagnosis",
    "diagnose_files_run": "estimation.streaming.diagnosis",
    "streamed_refit_selection": "estimation.streaming.diagnosis_selection",
    "f_tests": "estimation.streaming.candidate_screening",
    "file_sums": "estimation.streaming.chunks",
    "filter_margin": "estimation.streaming.chunks",
    "first_rows": "estimation.streaming.cutoff_choice",
    "identify_files": "estimation.streaming.identification",
    "identify_files_candidates": "estimation.streaming.identification",
    "streamed_repeated_motion": "estimation.streaming.model_selection",
    "summed_selection": "estimation.streaming.model_selection",
    "lag_one_correlation": "estimation.streaming.covariance",
    "plan_options": "estimation.streaming.periods",
    "streamed_recorded_errors": "estimation.streaming.recorded_errors",
    "streamed_recorded_mse": "estimation.streaming.recorded_errors",
    "scheduler_address": "estimation.streaming.settings",
    "streamed_plan": "estimation.streaming.recorded_errors",
    "streamed_window": "estimation.streaming.cutoff_choice",
    "sum_files": "estimation.streaming.cluster",
    "weighted_fit": "estimation.streaming.candidate_screening",
    "weighted_mse": "estimation.streaming.candidate_screening",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
