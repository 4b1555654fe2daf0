"""robot-oed: optimal experiment design and dynamic-parameter identification of robot manipulators.

The import packages are:

- :mod:`dynamics`: robot descriptions and the symbolic Newton–Euler regressors (CasADi);
- :mod:`oed`: excitation design (Fourier trajectories, APRBS), the verbs as library calls and the ``oed``
  command line;
- :mod:`estimation`: estimators (least squares, recursive least squares, Kalman fusion).

Each ``oed`` verb is a function here, taking the verb's options as keywords of the same names and returning a
run object (``to_dict()``, ``write(...)``, ``summary()``; :mod:`oed.workflows`)::

    import oed
    run = oed.identify(robot="puma560", joints=3, data="train.csv", validate="validate.csv")
    run.write("result.json")

Beside the verbs, the excitation design's names (``design_excitation``, ``FourierTrajectory``, ``JointBounds``,
the criteria, APRBS). The functions are imported on first use (``import oed`` stays light for the command line).
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

#: each verb function and the module of :mod:`oed.workflows` that holds it
VERB_FUNCTIONS: dict[str, str] = {
    "model": "model",
    "design": "design",
    "simulate": "simulate",
    "identify": "identify",
    "aprbs": "aprbs",
    "servo_simulate": "servo_simulate",
    "servo_fit": "servo_fit",
    "diagnose": "diagnose",
    "predict": "predict",
    "export": "export",
    "payload": "payload",
}

#: the other names users import from this package (excitation design, APRBS, criteria) and their modules; the
#: modules behind may move, these names stay
_EXPORTS: dict[str, str] = {
    "APRBSDesign": "oed.aprbs_signal",
    "AmplitudeCoverage": "oed.aprbs_signal",
    "CRITERIA": "oed.criteria",
    "ConditionNumber": "oed.criteria",
    "Criterion": "oed.criteria",
    "DesignError": "oed.excitation",
    "DesignResult": "oed.excitation",
    "DesignSettings": "oed.design_settings",
    "ExcitationDesign": "oed.design_problem",
    "FourierTrajectory": "oed.fourier",
    "InfeasibleBoundsError": "oed.bounds",
    "JointBounds": "oed.bounds",
    "LogDet": "oed.criteria",
    "MinEigenvalue": "oed.criteria",
    "PUMA_BOUNDS": "oed.bounds",
    "SUCCESS_STATUSES": "oed.design_problem",
    "ShrunkDesignWarning": "oed.excitation",
    "SpectralContent": "oed.aprbs_signal",
    "StartResult": "oed.design_problem",
    "WeightedSum": "oed.aprbs_signal",
    "compare_controllers": "oed.control",
    "criterion_from_name": "oed.criteria",
    "default_bounds": "oed.design_problem",
    "design_aprbs": "oed.aprbs_signal",
    "design_excitation": "oed.excitation",
    "hold_min_from_time_constant": "oed.aprbs_signal",
    "information_matrix": "oed.criteria",
    "ipopt_solver": "oed.design_solver",
    "jit_options": "oed.design_solver",
    "plot_aprbs": "oed.aprbs_figures",
    "plot_trajectory": "oed.design_plot",
    "random_aprbs": "oed.aprbs_signal",
    "random_fourier": "oed.fourier",
    "run_demo": "oed.demo",
    "sampled_information": "oed.design_solver",
    "sqp_solver": "oed.design_solver",
    "tracking_experiment": "oed.control",
    "unpack": "oed.fourier",
}

__all__ = ["__version__", *VERB_FUNCTIONS, *sorted(_EXPORTS)]


def __getattr__(name: str) -> Any:
    """The verb functions and the names of ``_EXPORTS``, imported when first asked for (PEP 562)."""
    if name in VERB_FUNCTIONS:
        module = importlib.import_module(f"oed.workflows.{VERB_FUNCTIONS[name]}")
        return getattr(module, name)
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'oed' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *VERB_FUNCTIONS, *_EXPORTS])
