"""Velocities and accelerations from measured positions: differentiation (filters, Fourier fits), periodicity, the preprocessing plan of an identification, the delay between torques and motion.

Modules: :mod:`~estimation.preprocessing.delay`, :mod:`~estimation.preprocessing.differentiation`, :mod:`~estimation.preprocessing.fourier_series`, :mod:`~estimation.preprocessing.periodicity`, :mod:`~estimation.preprocessing.plan`.
"""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "AverageChoice": "estimation.preprocessing.differentiation",
    "BlockFourierSums": "estimation.preprocessing.fourier_sums",
    "ButterworthDifferentiation": "estimation.preprocessing.differentiation",
    "CandidateEvidence": "estimation.preprocessing.plan",
    "DELAY": "estimation.preprocessing.delay",
    "DelayBounds": "estimation.preprocessing.delay",
    "DelayBoundsError": "estimation.preprocessing.delay",
    "Differentiation": "estimation.preprocessing.differentiation",
    "Evidence": "estimation.preprocessing.plan",
    "FourierDifferentiation": "estimation.preprocessing.differentiation",
    "FourierSeries": "estimation.preprocessing.fourier_series",
    "FrequencyMismatchWarning": "estimation.preprocessing.plan",
    "Preprocessing": "estimation.preprocessing.plan",
    "PreprocessingWarning": "estimation.preprocessing.plan",
    "SegmentTooShortForFilterError": "estimation.preprocessing.plan",
    "UniformFourierSums": "estimation.preprocessing.fourier_sums",
    "average_periods": "estimation.preprocessing.differentiation",
    "check_delay": "estimation.preprocessing.delay",
    "check_frequency": "estimation.preprocessing.plan",
    "chirp_sums": "estimation.preprocessing.fourier_sums",
    "choose_preprocessing": "estimation.preprocessing.plan",
    "compensate_hold": "estimation.preprocessing.differentiation",
    "decimate": "estimation.preprocessing.differentiation",
    "delayed": "estimation.preprocessing.delay",
    "design_matrix": "estimation.preprocessing.fourier_series",
    "detect_fundamental": "estimation.preprocessing.periodicity",
    "evaluate_series": "estimation.preprocessing.fourier_series",
    "fill_derivatives": "estimation.preprocessing.differentiation",
    "fit_fourier": "estimation.preprocessing.differentiation",
    "fit_series": "estimation.preprocessing.fourier_series",
    "fractional_turns": "estimation.preprocessing.fourier_sums",
    "frequency_mismatch": "estimation.preprocessing.periodicity",
    "gram_solution": "estimation.preprocessing.fourier_series",
    "longest_piece": "estimation.preprocessing.delay",
    "motion_bandwidth": "estimation.preprocessing.differentiation",
    "prepare": "estimation.preprocessing.plan",
    "repeats_exactly": "estimation.preprocessing.differentiation",
    "sampling_rate": "estimation.preprocessing.differentiation",
    "split_delay": "estimation.preprocessing.delay",
    "whole_periods": "estimation.preprocessing.differentiation",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
