"""The next experiment, designed from what the experiments already run left uncertain.

- :mod:`oed.sequential.jacobian`: the identified model's noise-weighted Jacobian in all its parameters (shapes included);
- :mod:`oed.sequential.prior`: the records' Fisher information under it;
- :mod:`oed.sequential.criteria`: D-, Ds- and worst-relative optimality (a ``--focus`` group) on the posterior
  information;
- :mod:`oed.sequential.starts`: screened starts, with slowed joints among the candidates;
- :mod:`oed.sequential.problem`: the excitation design problem with that prior and criterion;
- :mod:`oed.sequential.next_experiment`: one call, with the predicted standard deviations;
- :mod:`oed.sequential.discrimination`: the experiment that best tells two rival models apart;
- :mod:`oed.sequential.rivals`: the rival, from a model file or the runner-up a diagnosis kept;
- :mod:`oed.sequential.figure`: the new trajectory beside the old ones, at low speed.
"""

from __future__ import annotations

from dynamics.runtime.lazy import lazy_exports

#: each name users import from this package and the module that defines it; the modules behind may move,
#: these names stay (imported on first use, PEP 562, so that importing the package stays light)
_EXPORTS: dict[str, str] = {
    "FocusedLogDet": "oed.sequential.criteria",
    "NextExperiment": "oed.sequential.next_experiment",
    "NoRunnerUpError": "oed.sequential.rivals",
    "PredictedStd": "oed.sequential.next_experiment",
    "SEQUENTIAL_CRITERIA": "oed.sequential.criteria",
    "SEQUENTIAL_MAX_ITER": "oed.sequential.problem",
    "SequentialDesign": "oed.sequential.problem",
    "SequentialDesignError": "oed.sequential.jacobian",
    "WorstRelativeVariance": "oed.sequential.criteria",
    "check_bounds": "oed.sequential.next_experiment",
    "check_rivals": "oed.sequential.discrimination",
    "design_discriminating": "oed.sequential.discrimination",
    "design_next": "oed.sequential.next_experiment",
    "focus_names": "oed.sequential.criteria",
    "load_rival": "oed.sequential.rivals",
    "model_jacobian": "oed.sequential.jacobian",
    "plot_next_experiment": "oed.sequential.figure",
    "posterior_criterion": "oed.sequential.criteria",
    "predicted_std": "oed.sequential.next_experiment",
    "prior_information": "oed.sequential.prior",
    "read_records": "oed.sequential.prior",
    "runner_up_file": "oed.sequential.rivals",
    "screened_start": "oed.sequential.starts",
    "slowed_start": "oed.sequential.starts",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
