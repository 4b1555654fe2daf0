"""The next experiment, one call: prior, criterion, multi-start design and the standard deviations it predicts.

::

    model = IdentifiedModel.load("report.json")
    records = read_records(model, ["experiment1.csv"])
    next_experiment = design_next(model, records, bounds=PUMA_BOUNDS, focus="stribeck", starts=8)
    next_experiment.predicted.to_dict()["vs2"]     # {"value", "now", "after_repeat", "after_designed"}

The predicted standard deviations are the square roots of the diagonal of the inverse information
(:mod:`oed.sequential.prior`): ``now`` from the records, ``after_repeat`` had the first experiment been
run again for the new experiment's duration (its information scaled by the ratio of durations), and
``after_designed`` with the designed trajectory's (:class:`oed.sequential.problem.SequentialDesign`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from estimation.identification.identified_model import IdentifiedModel
from oed.bounds import JointBounds
from oed.excitation import DesignResult, DesignSettings, design_excitation
from oed.design_problem import StartResult
from oed.sequential.criteria import SequentialCriterionName, focus_names, posterior_criterion
from oed.sequential.jacobian import ModelJacobian, SequentialDesignError, model_jacobian
from oed.sequential.prior import PriorInformation, posterior_covariance, prior_information
from oed.sequential.problem import SEQUENTIAL_MAX_ITER, SequentialDesign

__all__ = ["NextExperiment", "PredictedStd", "check_bounds", "design_next", "predicted_std"]


@dataclass(frozen=True)
class PredictedStd:
    """Each parameter's estimate and its standard deviation now, after repeating the first experiment and after
    the designed one (module docstring)."""

    names: tuple[str, ...]
    value: NDArray[np.float64] = field(repr=False)
    now: NDArray[np.float64] = field(repr=False)
    after_repeat: NDArray[np.float64] = field(repr=False)
    after_designed: NDArray[np.float64] = field(repr=False)

    def to_dict(self) -> dict[str, dict[str, float]]:
        return {name: {"value": float(self.value[i]), "now": float(self.now[i]),
                       "after_repeat": float(self.after_repeat[i]), "after_designed": float(self.after_designed[i])}
                for i, name in enumerate(self.names)}

    def worst_relative(self, names: Sequence[str]) -> dict[str, float]:
        """The largest relative standard deviation ``σ/|value|`` among ``names``, now and after either experiment."""
        index = [self.names.index(name) for name in names]
        magnitude = np.abs(self.value[index])
        return {key: float(np.max(getattr(self, key)[index] / magnitude))
                for key in ("now", "after_repeat", "after_designed")}


def predicted_std(jacobian: ModelJacobian, prior: PriorInformation, designed: NDArray[np.float64],
                  duration_s: float) -> PredictedStd:
    """:class:`PredictedStd` from the prior, the designed experiment's information and its duration."""
    repeat = prior.information * (1.0 + duration_s / prior.duration_s)

    def std(information: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.sqrt(np.clip(np.diag(posterior_covariance(information)), 0.0, None))

    return PredictedStd(jacobian.names, jacobian.estimate, std(prior.information), std(repeat),
                        std(prior.information + designed))


@dataclass(frozen=True)
class NextExperiment:
    """The designed next experiment and what it is predicted to do."""

    design: DesignResult
    predicted: PredictedStd
    focus: tuple[str, ...]
    duration_s: float
    prior: PriorInformation = field(repr=False)
    designed_information: NDArray[np.float64] = field(repr=False)

    def to_dict(self) -> dict[str, Any]:
        """The design as ``oed design`` writes it, plus ``predicted_std`` and ``sequential`` (the prior's and the new
        experiment's durations, the focus and the worst relative standard deviation of the focus)."""
        document = self.design.trajectory.to_dict()
        document["predicted_std"] = self.predicted.to_dict()
        document["sequential"] = {
            "focus": list(self.focus), "duration_s": self.duration_s,
            "periods": self.duration_s * self.design.trajectory.frequency_hz,
            "prior_duration_s": self.prior.duration_s, "prior_samples": self.prior.n_samples,
            "sample_time_s": self.prior.sample_time_s,
            "worst_relative_std": self.predicted.worst_relative(self.focus),
        }
        return document

    def summary(self) -> str:
        """One line: the focus and its worst relative standard deviation now, after repeating, after the design."""
        worst = self.predicted.worst_relative(self.focus)
        shown = ", ".join(self.focus[:6]) + (f" and {len(self.focus) - 6} more" if len(self.focus) > 6 else "")
        return (f"focus {shown}: worst relative standard deviation now {100 * worst['now']:.3g} %, after repeating the "
                f"records {100 * worst['after_repeat']:.3g} %, after the designed experiment "
                f"{100 * worst['after_designed']:.3g} % ({self.duration_s:.3g} s)")


def check_bounds(bounds: JointBounds, model: IdentifiedModel) -> None:
    """Refuse bounds for another robot: another joint count, or joint names (when given) other than the model's."""
    if bounds.n_joints != model.robot.n_joints:
        raise SequentialDesignError(f"the bounds describe {bounds.n_joints} joints, the model's robot "
                                    f"{model.robot.name} has {model.robot.n_joints}")
    default = tuple(f"joint{i}" for i in range(1, bounds.n_joints + 1))
    if bounds.joint_names != default and tuple(bounds.joint_names) != tuple(model.file.joint_names):
        raise SequentialDesignError(f"the bounds name joints {', '.join(bounds.joint_names)}, the model "
                                    f"{', '.join(model.file.joint_names)}")


def design_next(model: IdentifiedModel, records: Measurements, *, bounds: JointBounds,
                settings: DesignSettings | None = None, focus: str | Sequence[str] | None = None,
                criterion: SequentialCriterionName | None = None, duration_s: float | None = None,
                starts: int = 8, seed: int | None = 0,
                progress: Callable[[StartResult, int], None] | None = None,
                constraints: tuple = ()) -> NextExperiment:
    """The next experiment after ``records`` that best determines the ``focus`` parameters (module docstring).

    Parameters
    ----------
    model
        The identified model (its estimate linearises the prediction).
    records
        The experiments already run, prepared (:func:`oed.sequential.prior.read_records`).
    bounds, settings, starts, seed, progress
        As :func:`oed.excitation.design_excitation`.
    focus
        Parameter or effect names (:func:`oed.sequential.criteria.focus_names`); ``None``: every parameter.
    criterion
        ``"d"`` (D-optimality on every parameter), ``"ds"`` (Ds: the focus group's marginal log det) or
        ``"worst-relative"`` (a smooth maximum of the focus group's relative variances,
        :class:`oed.sequential.criteria.WorstRelativeVariance`); default: ``"worst-relative"`` with a ``focus``,
        ``"d"`` without.
    duration_s
        Length of the new experiment, s (default: that of the records).
    constraints
        Torque limits, a floor, self-collision (:mod:`oed.design_constraints`), inside the optimisation.
    """
    check_bounds(bounds, model)
    jacobian = model_jacobian(model)
    prior = prior_information(jacobian, records)
    chosen = focus_names(jacobian, focus)
    kind = criterion or ("d" if focus is None else "worst-relative")
    duration = prior.duration_s if duration_s is None else float(duration_s)
    settings = settings or DesignSettings(max_iter=SEQUENTIAL_MAX_ITER, sqp_after=None)
    problem = SequentialDesign(model.robot, model.model.kind, bounds, posterior_criterion(jacobian, chosen, kind, prior=prior),
                               model.model.effects, settings, constraints=tuple(constraints), jacobian=jacobian,
                               prior=prior, duration_s=duration)
    result = design_excitation(model.robot, starts=starts, seed=seed, progress=progress, problem=problem)
    best = next(start for start in result.starts if start.index == result.best)
    designed = problem.designed_information(best.x)
    return NextExperiment(result, predicted_std(jacobian, prior, designed, duration), chosen, duration, prior, designed)
