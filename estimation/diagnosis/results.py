"""What a diagnosis returns, in memory (:func:`estimation.diagnosis.search.diagnose`) or from records read in
blocks and summed (:func:`estimation.streaming.diagnosis.diagnose_files`): one :class:`Diagnosis` with the effects
found, the candidates rejected and why, the model before and after, and the JSON document of ``oed diagnose``.

The streamed path fills the same fields; its models before and after are :class:`SummedFit` (an estimate from sums
and its errors per channel, no samples held) where the in-memory path has an
:class:`~estimation.identification.fit.IdentificationResult`, and what it cannot compute (the per-sample residual
statistics, tracing, whiteness…) is ``None``, each with its reason in :attr:`Diagnosis.not_computed`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from dynamics.effects.linear import Effect
from dynamics.models import IdentificationModel
from dynamics.effects.shaped import shape_parameters
from estimation.diagnosis.candidates.trials import candidate_label
from estimation.diagnosis.rules.robust_test import wald_test
from estimation.diagnosis.statistics import ResidualReport
from estimation.estimators.summed_least_squares import SummedEstimate
from estimation.identification.fit import IdentificationResult
from estimation.identification.model_file import DELAY_NAME
from estimation.identification.validation import ChannelErrors
from estimation.diagnosis.sign_constraints import PinnedTerm
from estimation.estimators.effect_blocks import effect_rows


@dataclass(frozen=True)
class FoundEffect:
    """An effect the data asked for, with its estimates in the augmented model."""

    name: str
    channels: tuple[str, ...]
    parameters: tuple[str, ...]
    values: tuple[float, ...]
    std: tuple[float, ...]
    p_value: float
    f_statistic: float
    spec: str = ""
    shape: dict[str, float] = field(default_factory=dict)
    shape_std: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name, "channels": list(self.channels), "parameters": list(self.parameters),
            "values": list(self.values), "std": list(self.std), "p_value": self.p_value, "f_statistic": self.f_statistic,
            "spec": self.spec or self.name, "shape": dict(self.shape), "shape_std": dict(self.shape_std),
        }


@dataclass(frozen=True)
class RejectedEffect:
    """A candidate that was not added, and why."""

    name: str
    channels: tuple[str, ...]
    reason: str
    spec: str = ""


@dataclass(frozen=True)
class RunnerUp:
    """The best rival model the diagnosis did not choose, fitted as the chosen one was
    (:mod:`estimation.diagnosis.runner_up`).

    ``spec``: its effects as a model file names them; ``instead``: what it has in place of the chosen
    model's effects; ``effects``: its effects beyond the declared ones, with their estimates;
    ``bic_gap``: its BIC minus the chosen model's on training (positive: the chosen is preferred);
    ``selection_bic_gap``: the same gap as the search ranked the two moves in round ``round``;
    ``model`` and ``fit``: the model and its estimate (an
    :class:`~estimation.identification.fit.IdentificationResult` in memory, a
    :class:`~estimation.estimators.summed_least_squares.SummedEstimate` from sums), for its model file;
    ``warnings``: its physically implausible estimates (not issued as warnings: the chosen model is the answer)."""

    spec: str
    instead: str
    effects: tuple[FoundEffect, ...]
    n_parameters: int
    bic_gap: float
    selection_bic_gap: float
    round: int
    train_mse: dict[str, float]
    validation_mse: dict[str, float] | None
    model: IdentificationModel = field(repr=False)
    fit: Any = field(repr=False)
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """The ``runner_up`` entry of ``report.json`` (its ``model_file`` is added by the verb that knows the robot's source)."""
        return {"spec": self.spec, "instead": self.instead, "effects": [effect.to_dict() for effect in self.effects],
                "n_parameters": self.n_parameters, "bic_gap": self.bic_gap,
                "selection_bic_gap": self.selection_bic_gap, "round": self.round,
                "train": {"mse": dict(self.train_mse)},
                "validation": {"mse": None if self.validation_mse is None else dict(self.validation_mse)},
                "warnings": list(self.warnings)}

    def shape(self) -> dict[str, float]:
        """The shapes of its shaped laws, by parameter name (its model file's ``shape``)."""
        return {name: float(value) for effect in self.effects for name, value in effect.shape.items()}

    def summary(self) -> str:
        """One line for the printed summary."""
        return (f"runner-up: {self.instead} (BIC {self.bic_gap:+.3g} against the chosen model; kept in the report "
                "for `oed design --discriminate`)")


@dataclass(frozen=True)
class SummedFit:
    """A model estimated from sums (the streamed diagnosis), with the fields of an
    :class:`~estimation.identification.fit.IdentificationResult` that a :class:`Diagnosis` reads: ``model``,
    ``estimate`` (a :class:`~estimation.estimators.summed_least_squares.SummedEstimate`), ``train`` and
    ``validation`` (:class:`ChannelErrors`), ``warnings``; ``cov_method``: how its covariance was had."""

    model: IdentificationModel
    estimate: SummedEstimate = field(repr=False)
    train: ChannelErrors
    validation: ChannelErrors
    warnings: tuple[str, ...] = ()
    cov_method: str = "classical"
    shapes: tuple[Any, ...] = ()
    delay: Any = None  # the adopted delay (a ShapeValue; the streamed diagnosis's), else None


#: what the streamed diagnosis cannot compute, by the document's key (``Diagnosis.not_computed``)
STREAMED_NOT_COMPUTED = {
    "residuals": "per-sample residual statistics need the residuals sample by sample, which the streamed path does "
                 "not hold",
    "tracing": "residual tracing needs the residuals sample by sample, which the streamed path does not hold",
    "whiteness": "whiteness checks need the residuals sample by sample, which the streamed path does not hold",
    "model_parameters": "the physical reading of the estimate is made in memory",
    "rest": "rest stretches are found in memory (the streamed path reads whole files)",
    "test": "--test is read in memory",
    # made by ``oed diagnose`` from the diagnosis's sums (estimation.streaming.diagnosis_selection), which drops them
    "consistent": "the physically consistent refit is made from the sums by oed diagnose "
                  "(estimation.streaming.diagnosis_selection), not by diagnose_files",
    "links": "the bodies of the physically consistent refit are had from the sums by oed diagnose "
             "(estimation.streaming.diagnosis_selection), not by diagnose_files",
    "model_selection": "the choice between the adopted model and its consistent refit is made from the sums by oed "
                       "diagnose (estimation.streaming.diagnosis_selection), not by diagnose_files",
    "gravity": "the diagnosis with the gravity a mount check found (or none) is a candidate of the default answer "
               "(estimation.consistent.mounted_gravity) made by oed diagnose, not by diagnose_files",
    "subtracted": "the diagnosis of the torques with the description's gravity torque added back (a log less that "
                  "load) is a candidate of the default answer (estimation.consistent.mounted_gravity) made by oed "
                  "diagnose, not by diagnose_files",
    "saturated_samples": "a torque or wrench sensor past its range (a channel held at its extreme while the robot moves) is "
                         "said streamed (SaturatedTorqueWarning: the whole record judged block by block, as in memory) "
                         "and its samples are left out of the streamed sums and errors as in memory (masked in that "
                         "channel only; the diagnosis's search, as memory's, leaves such a sample out whole); the "
                         "counts per record and segment are said in the warning, not collected by diagnose_files "
                         "(oed diagnose counts them: estimation.streaming.masked_counts)",
}


@dataclass(frozen=True)
class Diagnosis:
    """Result of a diagnosis, in memory (:func:`estimation.diagnosis.search.diagnose`) or streamed
    (:func:`estimation.streaming.diagnosis.diagnose_files`): the same fields on both paths.

    Attributes
    ----------
    effects, rejected
        The effects found (:class:`FoundEffect`) and the candidates not added, with why.
    before, after
        The declared and the augmented model fitted: an
        :class:`~estimation.identification.fit.IdentificationResult` in memory, a :class:`SummedFit` streamed;
        both have ``model``, ``estimate``, ``train.mse``, ``validation.mse`` and ``warnings``.
    residuals
        Per-sample residual statistics, or ``None`` (streamed: :attr:`not_computed` says why).
    statistics
        The noise floor and the errors against it, tracing and whiteness (``None`` inside where not computed).
    path
        ``"in-memory"`` or ``"streamed"`` (the document's ``diagnosis_path``).
    not_computed
        What this path could not compute, by the document's key, and why (empty in memory).
    trivial
        The validation MSE of the trivial predictors (``zero_mse``, ``nominal_mse``), or ``None``.
    streaming
        How the files were read, summed and estimated (the document's ``streaming``), or ``None`` in memory.
    swap
        The diagnosis with the mixed model of :mod:`estimation.diagnosis.plain_laws` adopted, when that model was
        refused only on the unconstrained fits' validation score: the default answer judges it on its candidates
        (:func:`oed.workflows.diagnose.judged_swap`); ``None`` otherwise.
    """

    effects: tuple[FoundEffect, ...]
    rejected: tuple[RejectedEffect, ...]
    before: IdentificationResult | SummedFit
    after: IdentificationResult | SummedFit
    residuals: dict[str, dict[str, float]] | None = field(repr=False)
    statistics: ResidualReport | None = field(default=None, repr=False)
    pinned: tuple[PinnedTerm, ...] = ()
    #: the best rival model not chosen (:mod:`estimation.diagnosis.runner_up`), or ``None`` and why
    runner_up: RunnerUp | None = field(default=None, repr=False)
    runner_up_reason: str | None = None
    path: Literal["in-memory", "streamed"] = "in-memory"
    not_computed: dict[str, str] = field(default_factory=dict, repr=False)
    trivial: dict[str, dict[str, float]] | None = field(default=None, repr=False)
    streaming: dict[str, Any] | None = field(default=None, repr=False)
    swap: Diagnosis | None = field(default=None, repr=False)

    @property
    def model(self) -> IdentificationModel:
        """The declared model."""
        return self.before.model

    @property
    def cov_method(self) -> str:
        """How the final estimate's covariance was had (the document's ``cov_method``)."""
        return self.after.cov_method if isinstance(self.after, SummedFit) else self.after.estimate.cov_method

    def final_model(self) -> IdentificationModel:
        """The declared model with the effects found: ``after`` holds its estimate (in the order of its columns)."""
        return self.after.model

    def final_shape(self) -> dict[str, float]:
        """The shapes of the shaped laws found, by parameter name."""
        return {name: float(value) for effect in self.effects for name, value in effect.shape.items()}

    def runner_up_shape(self) -> dict[str, float]:
        """The runner-up's model file's shapes (:meth:`RunnerUp.shape`) and the chosen model's adopted delay
        (:data:`~estimation.identification.model_file.DELAY_NAME`), along whose moved motion the runner-up is fitted
        on both paths (:mod:`estimation.diagnosis.runner_up`; in memory its fit carries that delay, from sums the
        sums are moved by it): what ``oed predict`` needs to move the motion alike. Empty without a runner-up."""
        if self.runner_up is None:
            return {}
        delay = self.final_shape().get(DELAY_NAME)
        return {**self.runner_up.shape(), **({} if delay is None else {DELAY_NAME: delay})}

    def to_dict(self) -> dict[str, Any]:
        """The JSON document of ``oed diagnose`` (the same keys on both paths; ``None`` where :attr:`not_computed`
        says why)."""
        document = {
            "robot": self.before.model.robot.name,
            "model": self.before.model.kind.value,
            "declared_effects": [effect.name for effect in self.before.model.effects],
            "effects": [effect.to_dict() for effect in self.effects],
            "rejected": [{"name": r.name, "spec": r.spec or r.name, "channels": list(r.channels), "reason": r.reason}
                         for r in self.rejected],
            "residuals": self.residuals,
            "warnings": {"before": list(self.before.warnings), "after": list(self.after.warnings)},
            "train": {"before": {"mse": self.before.train.mse}, "after": {"mse": self.after.train.mse}},
            "validation": {
                "before": {"mse": self.before.validation.mse if self.before.validation else None},
                "after": {"mse": self.after.validation.mse if self.after.validation else None},
            },
            "cov_method": self.cov_method,
            "pinned": [term.to_dict() for term in self.pinned],
            "runner_up": None if self.runner_up is None else self.runner_up.to_dict(),
            "runner_up_reason": self.runner_up_reason,
        }
        if self.statistics is not None:  # noise floor, tracing, whiteness (estimation.diagnosis.statistics)
            document.update(self.statistics.to_dict())
            for which in ("before", "after"):
                document["validation"][which]["mse_over_floor"] = self.statistics.ratios(which) or None
        if self.trivial is not None:  # the trivial predictors' validation errors
            document["validation"].update({key: dict(value) for key, value in self.trivial.items()})
        document.update({key: None for key in self.not_computed if key not in document})
        document["diagnosis_path"] = self.path
        document["streaming"] = None if self.streaming is None else dict(self.streaming)
        document["not_computed"] = dict(self.not_computed)
        return document


def runner_up_line(runner_up: RunnerUp | None, reason: str | None) -> str:
    """The summary's line on the runner-up, or on why there is none."""
    return runner_up.summary() if runner_up is not None else f"runner-up: none ({reason})"


def found_effect(after: IdentificationResult, effect: Effect, p_value: float, statistic: float,
           model: IdentificationModel) -> FoundEffect:
    names = list(after.estimate.names)
    parameters = tuple(effect.parameter_names(model.robot))
    indices = [names.index(name) for name in parameters]
    shape_names = {parameter.name for parameter in shape_parameters(effect, model.robot)}
    shapes = {value.name: value for value in after.shapes if value.name in shape_names}
    return FoundEffect(
        name=effect.name,
        channels=tuple(model.channels[row] for row in effect_rows(model.kind, model.robot, effect, model.n_channels)),
        parameters=parameters,
        values=tuple(float(after.estimate.values[i]) for i in indices),
        std=tuple(float(after.estimate.std[i]) for i in indices),
        p_value=p_value,
        f_statistic=float(statistic),
        spec=candidate_label(effect),
        shape={name: value.value for name, value in shapes.items()},
        shape_std={name: value.std for name, value in shapes.items()},
    )


def found_delay(after: IdentificationResult, trial: Any, model: IdentificationModel) -> tuple[FoundEffect, ...]:
    """The adopted delay (``trial``: :class:`estimation.diagnosis.candidates.delay.DelayTrial`, or ``None``) as a
    found effect: no linear coefficients, its value a shape parameter."""
    if trial is None or after.delay is None:
        return ()
    test = wald_test(np.array([after.delay.value]), np.array([[after.delay.std**2]]))  # as the other findings
    return (FoundEffect(name="delay", channels=tuple(model.channels), parameters=(), values=(), std=(),
                        p_value=test.p_value, f_statistic=test.f_statistic, spec="delay",
                        shape={"delay": after.delay.value}, shape_std={"delay": after.delay.std}),)
