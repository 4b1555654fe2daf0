"""Close the loop on measured data: find what an identified model lacks, add it, report before/after.

Procedure (forward selection on nested linear models):

1. Identify the declared model by channel-weighted least squares; keep its channel weights
   ``w_c = 1/σ_c²`` fixed for the comparisons that follow.
2. For every candidate effect (one column block per joint or plate channel: ``coulomb``,
   ``offset``, ``armature``, ``stribeck``, ``spring``, ``wrench_offset``, or a user's own
   :class:`dynamics.effects.Effect`) check first that it is **identifiable**: the base-parameter
   count of the augmented model must grow by the candidate's column count; otherwise the base
   parameters already absorb it and it is reported as such, never added.
3. Fit each identifiable candidate on the training data and test the nested models with the
   F statistic ``F = ((RSS₀ − RSS₁)/k) / (RSS₁/(N m − p₁))`` on weighted residual sums of
   squares; the threshold is ``alpha`` divided by the number of candidates (Bonferroni).
4. The most significant candidate is added only if its estimate has the physical sign (Coulomb,
   Stribeck, armature: positive) and it lowers the weighted validation error on the held-out
   data by at least ``min_improvement``; then the search repeats. It stops when nothing
   significant remains.
5. Re-identify the augmented model and report the validation MSE per channel before and after.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import casadi
import numpy as np
import scipy.stats
from numpy.typing import NDArray

from dynamics.effects import (
    POSITIVE_EFFECTS,
    WRENCH_CHANNELS,
    Armature,
    CoulombFriction,
    Effect,
    JointOffset,
    Spring,
    StribeckFriction,
    WrenchOffset,
)
from dynamics.models import IdentificationModel, ModelKind, build_model
from dynamics.threads import single_threaded_blas
from estimation.coupling_candidates import coupling_candidates
from estimation.identification import IdentificationResult, identify
from estimation.least_squares import stack
from estimation.diagnosis_statistics import ResidualReport, residual_report
from estimation.measurements import Measurements
from estimation.noise_floor import NoiseFloor
from estimation.whiteness import autocorrelation

JOINT_CANDIDATES: tuple[type, ...] = (CoulombFriction, JointOffset, Armature, StribeckFriction, Spring)


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

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name, "channels": list(self.channels), "parameters": list(self.parameters),
            "values": list(self.values), "std": list(self.std), "p_value": self.p_value, "f_statistic": self.f_statistic,
        }


@dataclass(frozen=True)
class RejectedEffect:
    """A candidate that was not added, and why."""

    name: str
    channels: tuple[str, ...]
    reason: str


@dataclass(frozen=True)
class Diagnosis:
    """Result of :func:`diagnose`."""

    effects: tuple[FoundEffect, ...]
    rejected: tuple[RejectedEffect, ...]
    before: IdentificationResult
    after: IdentificationResult
    residuals: dict[str, dict[str, float]] = field(repr=False)
    statistics: ResidualReport | None = field(default=None, repr=False)

    def to_dict(self) -> dict[str, Any]:
        """The JSON document of ``oed diagnose``."""
        document = {
            "robot": self.before.model.robot.name,
            "model": self.before.model.kind.value,
            "declared_effects": [effect.name for effect in self.before.model.effects],
            "effects": [effect.to_dict() for effect in self.effects],
            "rejected": [{"name": r.name, "channels": list(r.channels), "reason": r.reason} for r in self.rejected],
            "residuals": self.residuals,
            "warnings": {"before": list(self.before.warnings), "after": list(self.after.warnings)},
            "train": {"before": {"mse": self.before.train.mse}, "after": {"mse": self.after.train.mse}},
            "validation": {
                "before": {"mse": self.before.validation.mse if self.before.validation else None},
                "after": {"mse": self.after.validation.mse if self.after.validation else None},
            },
            "cov_method": self.after.estimate.cov_method,
        }
        if self.statistics is not None:  # noise floor, tracing, whiteness (estimation.diagnosis_statistics)
            document.update(self.statistics.to_dict())
            for which in ("before", "after"):
                document["validation"][which]["mse_over_floor"] = self.statistics.ratios(which) or None
        return document


def effect_channels(effect: Effect, model: IdentificationModel) -> tuple[str, ...]:
    """The model channels an effect's columns reach."""
    values = _columns_at_random_states(model, effect)
    return tuple(channel for channel, row in zip(model.channels, values) if np.any(row != 0))


def default_candidates(model: IdentificationModel) -> tuple[Effect, ...]:
    """One candidate per joint for each joint effect, one per plate channel for the offsets.

    Candidates already in the model are left out.
    """
    declared = {(effect.name, parameter) for effect in model.effects for parameter in effect.parameter_names(model.robot)}
    candidates: list[Effect] = []
    if model.kind is not ModelKind.EXTERNAL:
        for effect_type in JOINT_CANDIDATES:
            for joint in range(model.robot.n_joints):
                candidate = effect_type(joints=(joint,))
                if (candidate.name, candidate.parameter_names(model.robot)[0]) not in declared:
                    candidates.append(candidate)
    if model.kind is not ModelKind.INTERNAL:
        for channel in WRENCH_CHANNELS:
            candidate = WrenchOffset(channels=(channel,))
            if (candidate.name, candidate.parameter_names(model.robot)[0]) not in declared:
                candidates.append(candidate)
    return tuple(candidates)


@functools.lru_cache(maxsize=256)
def _columns_function(model: IdentificationModel, effect: Effect) -> casadi.Function:
    q, dq, ddq = (casadi.SX.sym(name, model.robot.n_joints) for name in ("q", "dq", "ddq"))
    joint_columns, wrench_columns = effect.columns(model.robot, q, dq, ddq)
    count = len(effect.parameter_names(model.robot))
    joint_block = joint_columns if joint_columns is not None else casadi.SX.zeros(model.robot.n_joints, count)
    wrench_block = wrench_columns if wrench_columns is not None else casadi.SX.zeros(6, count)
    block = {
        ModelKind.INTERNAL: joint_block,
        ModelKind.EXTERNAL: wrench_block,
        ModelKind.COMBINED: casadi.vertcat(wrench_block, joint_block),
    }[model.kind]
    label = re.sub(r"_+", "_", re.sub(r"\W", "_", effect.name)).strip("_")  # coulomb[q5+q6]: not a CasADi name
    return casadi.Function(f"{label}_columns", [q, dq, ddq], [casadi.densify(block).T], ["q", "dq", "ddq"], ["Ct"])


def _columns_at_random_states(model: IdentificationModel, effect: Effect) -> NDArray[np.float64]:
    generator = np.random.default_rng(0)
    states = [generator.normal(size=model.robot.n_joints) for _ in range(3)]
    return np.asarray(_columns_function(model, effect)(*states)).T  # (m, k)


def candidate_columns(model: IdentificationModel, effect: Effect, measurements: Measurements) -> NDArray[np.float64]:
    """The candidate's columns over the samples, ``(N, m, k)``."""
    function = _columns_function(model, effect).map(measurements.n_samples)
    values = np.asarray(function(measurements.q.T, measurements.dq.T, measurements.ddq.T))  # (k, m·N)
    return values.T.reshape(measurements.n_samples, model.n_channels, -1)


def _weighted_fit(Y: NDArray[np.float64], y: NDArray[np.float64], weights: NDArray[np.float64]):
    """Least squares with fixed channel weights; ``(theta, weighted RSS)``."""
    root = np.sqrt(weights)
    A = (Y * root[None, :, None]).reshape(-1, Y.shape[2])
    b = (y * root[None, :]).reshape(-1)
    theta, *_ = np.linalg.lstsq(A, b, rcond=None)
    return theta, float(np.sum((A @ theta - b) ** 2))


def _weighted_mse(Y, y, theta, weights) -> float:
    return float(np.sum(np.mean((y - Y @ theta) ** 2, axis=0) * weights))


def residual_statistics(result: IdentificationResult, *, lags: Sequence[int] = (1, 10, 100)) -> dict[str, dict[str, float]]:
    """Per channel: mean, standard deviation, RMS and autocorrelation of the training residuals.

    White residuals have autocorrelations near 0 at every lag; a structured residual (an
    unmodelled effect) keeps them near 1.
    """
    residuals = result.estimate.residuals
    statistics = {}
    for channel, values in zip(result.estimate.channels, residuals.T):
        entry = {"mean": float(values.mean()), "std": float(values.std()), "rms": float(np.sqrt(np.mean(values**2)))}
        correlation = autocorrelation(values, max((lag for lag in lags if lag < values.shape[0]), default=0))
        for lag in lags:
            if lag < values.shape[0]:  # normalised estimator: within [-1, 1] (estimation.whiteness)
                entry[f"autocorrelation_lag{lag}"] = float(correlation[lag])
        statistics[channel] = entry
    return statistics


@single_threaded_blas()
def diagnose(
    model: IdentificationModel,
    train: Measurements,
    validate: Measurements,
    *,
    candidates: Iterable[Effect] | None = None,
    alpha: float = 1e-3,
    min_improvement: float = 0.01,
    max_effects: int = 10,
    noise_floor: NoiseFloor | None = None,
) -> Diagnosis:
    """Find, by forward selection, the effects ``model`` lacks in ``train``, confirmed on ``validate``.

    Parameters
    ----------
    model
        The declared model (internal, external or combined, with its effects).
    train, validate
        Measurements with ``q, dq, ddq`` and the model's channels, from different experiments.
    candidates
        Effects to try (default: :func:`default_candidates` and the joint pairs the residual traces,
        :func:`estimation.coupling_candidates.coupling_candidates`).
    alpha
        Family-wise significance level of the F test (Bonferroni over the candidates).
    min_improvement
        Smallest relative decrease of the weighted validation MSE for an effect to be added.
    max_effects
        Most effects added.
    noise_floor
        Noise floor of the validation record as recorded (:func:`estimation.noise_floor.noise_floor`,
        before preprocessing; scaled here for the averaging/filtering ``validate.metadata`` records).
        ``None``: estimated from ``validate`` when it can be (see
        :mod:`estimation.diagnosis_statistics`), the method said in the report.
    """
    for name, data in (("train", train), ("validate", validate)):
        if not isinstance(data, Measurements):
            raise TypeError(f"{name} must be Measurements (diagnose confirms every effect on held-out data), "
                            f"got {type(data).__name__}")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha}")
    if not 0 <= min_improvement < 1:
        raise ValueError(f"min_improvement must lie in [0, 1), got {min_improvement}")
    candidates = tuple(default_candidates(model) + coupling_candidates(model, train=train)  # coulomb[q5+q6] …
                       if candidates is None else candidates)
    for candidate in candidates:
        if not isinstance(candidate, Effect):
            raise TypeError(f"candidate {candidate!r} is not an effect")
    before = identify(model, train, validate)
    weights = before.estimate.weights if before.estimate.method == "wls" else 1.0 / before.estimate.channel_variance
    threshold = alpha / max(len(candidates), 1)
    problem_train, problem_validate = stack(model, train), stack(model, validate)
    Y_train, Y_validate = problem_train.Y, problem_validate.Y
    y_train, y_validate = problem_train.y, problem_validate.y
    theta, rss = _weighted_fit(Y_train, y_train, weights)
    validation_error = _weighted_mse(Y_validate, y_validate, theta, weights)

    current = model
    selected: list[tuple[Effect, float, float]] = []
    rejected: dict[int, RejectedEffect] = {}
    remaining = list(range(len(candidates)))
    while remaining and len(selected) < max_effects:
        trials = []
        for index in remaining:
            candidate = candidates[index]
            channels = effect_channels(candidate, model)
            if not channels:
                rejected[index] = RejectedEffect(candidate.name, (), "has no rows in this model")
                continue
            count = len(candidate.parameter_names(model.robot))
            augmented = build_model(model.robot, model.kind, current.effects + (candidate,))
            if augmented.n_base < current.n_base + count:
                rejected[index] = RejectedEffect(
                    candidate.name, channels, "not identifiable: the base parameters already absorb it"
                )
                continue
            columns_train = candidate_columns(model, candidate, train)
            theta_aug, rss_aug = _weighted_fit(np.concatenate([Y_train, columns_train], axis=2), y_train, weights)
            dof = y_train.size - Y_train.shape[2] - count
            statistic = ((rss - rss_aug) / count) / (rss_aug / dof)
            p_value = float(scipy.stats.f.sf(statistic, count, dof))
            trials.append((p_value, -statistic, index, columns_train, theta_aug, rss_aug))
        remaining = [index for index in remaining if index not in rejected]
        added = False
        for p_value, negative_statistic, index, columns_train, theta_aug, rss_aug in sorted(trials, key=lambda t: (t[0], t[1])):
            if p_value >= threshold:
                break
            candidate = candidates[index]
            count = len(candidate.parameter_names(model.robot))
            if getattr(candidate, "physical_kind", candidate.name) in POSITIVE_EFFECTS and np.any(theta_aug[-count:] <= 0):
                rejected[index] = RejectedEffect(
                    candidate.name, effect_channels(candidate, model),
                    f"significant on training (p = {p_value:.2g}) but estimated with a non-physical sign",
                )
                continue
            columns_validate = candidate_columns(model, candidate, validate)
            Y_validate_aug = np.concatenate([Y_validate, columns_validate], axis=2)
            error = _weighted_mse(Y_validate_aug, y_validate, theta_aug, weights)
            if error >= (1.0 - min_improvement) * validation_error:
                rejected[index] = RejectedEffect(
                    candidate.name, effect_channels(candidate, model),
                    f"significant on training (p = {p_value:.2g}) but " + (f"raises the validation error" if error > validation_error else f"lowers the validation error by less than {100 * min_improvement:g} %") + f" ({validation_error:.4g} -> {error:.4g})",
                )
                continue
            selected.append((candidate, p_value, -negative_statistic))
            current = build_model(model.robot, model.kind, current.effects + (candidate,))
            Y_train = np.concatenate([Y_train, columns_train], axis=2)
            Y_validate = Y_validate_aug
            rss, validation_error = rss_aug, error
            remaining.remove(index)
            added = True
            break
        remaining = [index for index in remaining if index not in rejected]
        if not added:
            break
    reason = f"not tested: {max_effects} effects already added" if len(selected) >= max_effects else "not significant"
    for index in remaining:
        rejected.setdefault(index, RejectedEffect(candidates[index].name, effect_channels(candidates[index], model), reason))

    after = identify(current, train, validate) if selected else before
    names = list(after.estimate.names)
    found = []
    for candidate, p_value, statistic in selected:
        parameters = tuple(candidate.parameter_names(model.robot))
        indices = [names.index(name) for name in parameters]
        found.append(
            FoundEffect(
                name=candidate.name,
                channels=effect_channels(candidate, model),
                parameters=parameters,
                values=tuple(float(after.estimate.values[i]) for i in indices),
                std=tuple(float(after.estimate.std[i]) for i in indices),
                p_value=p_value,
                f_statistic=float(statistic),
            )
        )
    return Diagnosis(
        effects=tuple(found),
        rejected=tuple(rejected[index] for index in sorted(rejected)),
        before=before,
        after=after,
        residuals=residual_statistics(before),
        statistics=residual_report(before, after, train, validate, noise_floor),
    )
