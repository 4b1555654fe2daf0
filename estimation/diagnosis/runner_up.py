"""The runner-up of a diagnosis: the best rival model the search did not choose, kept with its fit, so
that the next experiment can be designed to tell the two apart (``oed design --from report.json
--discriminate``).

**Which model.** At the search's last adopted move (:class:`estimation.diagnosis.forward_selection.DiagnosisSearch`;
the last adoption of an effect: a delay, which moves the records rather than adding columns, is kept as
the chosen model has it), every move of that round was fitted against the model of the moment and ranked
by its BIC against it (:meth:`~estimation.diagnosis.forward_selection.DiagnosisSearch.rank`, the search's
own ranking). The runner-up is the model the search would have ended with had it taken, at that move,
the best-ranked of

* another move of the round: typically another friction law on the same joint (the sign law in place of
  a Stribeck law), or an effect elsewhere;
* no move: the model without the last adopted effect (BIC 0 against the model of the moment).

A move that is the chosen one plus more (a law with its joint's offset beside the law alone) is left
out: whether more is needed is what the next round asked, and it answered no. So is the law the move
replaced refitted in its place (that is the model of the moment: "no move"), and any rival that comes
out as the chosen model (a law the final refit simplified into the rival's). When the search adopted
nothing, the runner-up is the best-ranked move of its first round (the declared model and one
candidate); when no move was fitted at all (no candidates, the cap on effects, or the stopping rule
before a first round) there is none, and ``runner_up_reason`` says why.

**Why the BIC ranks them.** The held-out validation error, which confirms a move, was measured only for
the moves the search tried to confirm; the BIC was computed for every move of the round. The
runner-up's validation error, from its own fit, is reported beside.

**Its fit.** The rival model is identified as the chosen one was: in memory by
:func:`estimation.identification.fit.identify` (every shape refitted jointly from where the search left
it, along the records moved by the chosen model's delay); on the streamed path from the summed normal
equations at the shapes the subsample fixed (classical covariance: the batch-means pass is run for the
chosen model only). Its ``bic_gap`` is ``BIC_runner-up − BIC_chosen = Σ_c (RSS_c' − RSS_c) / σ_c² +
(p' − p) ln(N m)`` on training, ``σ_c²`` the chosen model's channel variances, ``p`` the linear and
shape parameters, ``N m`` the channel samples: the χ² form the discriminating design's
``expected_delta_bic`` uses (:mod:`oed.sequential.discrimination`). Positive: the data prefer the chosen
model by that much. It can come out negative, the search having ranked the moves before the joint refit of the
shapes: the two models are then within the noise of each other, which is what a discriminating experiment is for.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dynamics.effects.shaped import shape_parameters
from dynamics.effects.specs import effect_spec
from dynamics.models import IdentificationModel, build_model
from estimation.diagnosis.candidates.delay import DelayTrial
from estimation.diagnosis.candidates.delay_search import with_delay
from estimation.diagnosis.candidates.trials import Trial, candidate_label
from estimation.diagnosis.forward_selection import DiagnosisSearch, SearchOutcome
from estimation.diagnosis.results import FoundEffect, RunnerUp
from estimation.diagnosis.rules.robust_test import estimate_test
from estimation.estimators.effect_blocks import Block, ShapeSearchError
from estimation.identification.fit import ImplausibleEstimateWarning, identify
from estimation.identification.shaped import ShapeValue
from estimation.preprocessing.delay import delayed

__all__ = ["Alternative", "LastMove", "RivalFit", "RivalFitter", "RivalAhead", "RunnerUpOutcome", "RunnerUpSearch", "bic_gap",
           "fit_runner_up", "in_memory_fitter", "model_spec", "no_runner_up_reason", "rival_effects", "rival_models",
           "rivals",
           "with_runner_up"]

#: rivals tried, best-ranked first, whose fit fails (shapes the data do not determine) before giving up
MAX_FAILED_FITS = 3
#: why there is no runner-up when the search fitted no move
NOTHING_TRIED = "no move was fitted (no candidates, the cap on effects, or the stopping rule before a first round)"


@dataclass(frozen=True)
class Alternative:
    """A move of the round of the last adopted move, as the model of the moment changes by it: candidate
    indices ``adds`` (at ``shapes``) in, ``removes`` out; its BIC against the model of the moment."""

    adds: tuple[int, ...]
    removes: tuple[int, ...]
    shapes: Mapping[int, NDArray[np.float64]]
    bic: float


@dataclass(frozen=True)
class LastMove:
    """The search's last adopted move (``chosen``, or ``None`` when it adopted nothing), in search round
    ``round``, and the other moves of that round, best-ranked first."""

    round: int
    chosen: Alternative | None
    alternatives: tuple[Alternative, ...]

    def rival(self, final: Sequence[int], alternative: Alternative) -> tuple[int, ...]:
        """The candidate indices of the model the search would have ended with, ``final`` its adopted ones,
        had it taken ``alternative`` instead of the chosen move."""
        chosen = self.chosen or Alternative((), (), {}, 0.0)
        kept = [index for index in final if index not in chosen.adds]
        kept += [index for index in chosen.removes if index not in kept]
        kept = [index for index in kept if index not in alternative.removes]
        return tuple(kept + [index for index in alternative.adds if index not in kept])

    def gap(self, alternative: Alternative) -> float:
        """The alternative's BIC minus the chosen move's, as the search ranked them."""
        return alternative.bic - (0.0 if self.chosen is None else self.chosen.bic)


@dataclass(frozen=True)
class RunnerUpOutcome(SearchOutcome):
    """:class:`~estimation.diagnosis.forward_selection.SearchOutcome` with the last adopted move's round."""

    last_move: LastMove | None = None


def _alternative(trial: Trial, bic: float, adopted: Sequence[Any]) -> Alternative:
    shapes = {item.index: item.shape for item in adopted if item.index in trial.without}  # restored if not taken
    shapes.update(zip(trial.group, trial.shapes()))
    return Alternative(tuple(trial.group), tuple(trial.without), shapes, float(bic))


class RunnerUpSearch(DiagnosisSearch):
    """The diagnosis's search, keeping the moves of the round of its last adopted move (module docstring)."""

    last_move: LastMove | None = None

    def choose(self, trials, springs_beaten):
        """The search's choice, unchanged; when it adopts an effect (or adopted nothing yet), the round's
        other moves kept, best-ranked first (with "no move" when it adopts one)."""
        chosen = super().choose(trials, springs_beaten)
        if chosen is None and self.last_move is not None:
            return chosen
        if chosen is not None and isinstance(chosen[0], DelayTrial):
            return chosen  # the delay stays as the chosen model has it
        move = None if chosen is None else _alternative(chosen[0], self.rank(chosen[0])[0], self.adopted)
        others = []
        for trial in sorted((trial for trial in trials if isinstance(trial, Trial)), key=self.rank):
            if chosen is not None and trial is chosen[0] or trial.group == trial.without:
                continue  # the move itself, or an adopted law refitted in its place (the model of the moment)
            if move is not None and set(move.adds) <= set(trial.group):
                continue  # the chosen move and more: the next round's question
            others.append(_alternative(trial, self.rank(trial)[0], self.adopted))
        if move is not None:
            others.append(Alternative((), (), {}, 0.0))  # no move
            others.sort(key=lambda alternative: alternative.bic)
        self.last_move = LastMove(self.rounds, move, tuple(others))
        return chosen

    def run(self) -> RunnerUpOutcome:
        """The search's outcome, with its :class:`LastMove`."""
        outcome = super().run()
        return RunnerUpOutcome(**{item.name: getattr(outcome, item.name) for item in fields(SearchOutcome)},
                               last_move=self.last_move)


def no_runner_up_reason(outcome: SearchOutcome) -> str | None:
    """Why a search's outcome has no rival at all, or ``None``."""
    last = getattr(outcome, "last_move", None)
    return NOTHING_TRIED if last is None or not last.alternatives else None


def rivals(outcome: RunnerUpOutcome) -> list[tuple[tuple[int, ...], dict[int, NDArray[np.float64]], Alternative]]:
    """Each rival model, best-ranked first: its candidate indices in order, their shapes by index, and the move
    that makes it (rivals that come out as the search's final model left out)."""
    last = outcome.last_move
    if last is None:
        return []
    final = [item.index for item in outcome.adopted]
    shapes = {item.index: item.shape for item in outcome.adopted}
    found, seen = [], {frozenset(final)}
    for alternative in last.alternatives:
        indices = last.rival(final, alternative)
        if frozenset(indices) in seen:
            continue
        seen.add(frozenset(indices))
        merged = {**shapes, **(last.chosen.shapes if last.chosen else {}), **alternative.shapes}
        found.append((indices, {index: merged[index] for index in indices if index in merged}, alternative))
    return found


def instead(rival: Sequence[Block], chosen: Sequence[Block], model: IdentificationModel) -> str:
    """What the rival has in place of the chosen model's effects, in words."""
    def named(items: Sequence[Block]) -> str:
        return " + ".join(f"{candidate_label(block.effect)} on {', '.join(model.channels[r] for r in block.rows)}"
                          for block in items)
    added = [block for block in rival if all(block is not other for other in chosen)]
    removed = [block for block in chosen if all(block is not other for other in rival)]
    if added and removed:
        return f"{named(added)} in place of {named(removed)}"
    return f"without {named(removed)}" if removed else f"with {named(added)}"


def channel_rss(estimate: Any) -> NDArray[np.float64]:
    """Per channel, the training residual sum of squares of an estimate (in memory or from sums)."""
    if hasattr(estimate, "channel_rss"):
        return np.asarray(estimate.channel_rss, dtype=float)
    return np.sum(np.asarray(estimate.residuals, dtype=float) ** 2, axis=0)


def bic_gap(rival_rss: NDArray[np.float64], chosen_rss: NDArray[np.float64], variance: NDArray[np.float64],
            n_rows: int, rival_parameters: int, chosen_parameters: int) -> float:
    """``Σ_c (RSS_c' − RSS_c) / σ_c² + (p' − p) ln(N m)`` (module docstring)."""
    chi2 = float(np.sum((np.asarray(rival_rss) - np.asarray(chosen_rss)) / np.asarray(variance, dtype=float)))
    return chi2 + (rival_parameters - chosen_parameters) * float(np.log(n_rows))


@dataclass(frozen=True)
class RivalFit:
    """A rival model's fit: its ``estimate`` (``names, values, cov, channel_variance, records()`` and the
    residuals or their sums), its MSE per channel on training and validation against the channels as
    recorded, its fitted ``shapes`` (and their ``shape_std`` when estimated), the ``result`` its model
    file is written from, and its physically implausible estimates (``warnings``)."""

    estimate: Any
    train_mse: dict[str, float]
    validation_mse: dict[str, float] | None
    shapes: Mapping[str, float]
    shape_std: Mapping[str, float]
    result: Any
    warnings: tuple[str, ...] = ()


#: ``fit(model, indices, shape starts)``: the rival model (the declared one with the candidates ``indices``) fitted
RivalFitter = Callable[[IdentificationModel, tuple[int, ...], dict[str, float]], RivalFit]


def rival_effects(model: IdentificationModel, blocks: Sequence[Block], fit: RivalFit) -> tuple[FoundEffect, ...]:
    """The rival's effects beyond the declared ones with their estimates, as the report's ``effects`` list them
    (the p-value: the Wald test from the estimate's own covariance)."""
    records = {record["name"]: record for record in fit.estimate.records()}
    found = []
    for block in blocks:
        names = tuple(name for name in block.effect.parameter_names(model.robot) if name in records)
        shape_names = [parameter.name for parameter in shape_parameters(block.effect, model.robot)]
        test = estimate_test(fit.estimate, names)
        found.append(FoundEffect(
            name=block.effect.name, channels=tuple(model.channels[row] for row in block.rows), parameters=names,
            values=tuple(records[name]["value"] for name in names), std=tuple(records[name]["std"] for name in names),
            p_value=test.p_value, f_statistic=test.f_statistic, spec=candidate_label(block.effect),
            shape={name: float(fit.shapes[name]) for name in shape_names if name in fit.shapes},
            shape_std={name: float(fit.shape_std[name]) for name in shape_names if name in fit.shape_std}))
    return tuple(found)


def _shape_starts(model: IdentificationModel, blocks: Sequence[Block], indices: Sequence[int],
                  shapes: Mapping[int, NDArray[np.float64]]) -> dict[str, float]:
    return {parameter.name: float(value) for block, index in zip(blocks, indices) if index in shapes
            for parameter, value in zip(shape_parameters(block.effect, model.robot), shapes[index])}


def n_parameters(model: IdentificationModel, estimate: Any) -> int:
    """The linear coefficients of ``estimate`` and the shape parameters of ``model``'s effects."""
    return len(estimate.names) + sum(len(shape_parameters(effect, model.robot)) for effect in model.effects)


def _rows_count(estimate: Any) -> int:
    """The channel samples ``N m`` of an estimate (in memory or from sums)."""
    if hasattr(estimate, "n_samples"):
        return int(estimate.n_samples) * len(estimate.channels)
    return int(np.asarray(estimate.residuals).size)


def rival_models(declared: IdentificationModel, outcome: RunnerUpOutcome, blocks: Mapping[int, Block]
                 ) -> Iterator[tuple[tuple[int, ...], tuple[Block, ...], IdentificationModel, dict[str, float],
                                     Alternative]]:
    """Each rival best-ranked first (:func:`rivals`): its candidate indices and blocks, its model, the starts of its
    shapes, and the move that makes it; a rival that would hold one coefficient twice is none (no model)."""
    for indices, shapes, alternative in rivals(outcome):
        rival_blocks = tuple(blocks[index] for index in indices)
        try:
            model = build_model(declared.robot, declared.kind,
                                tuple(declared.effects) + tuple(block.effect for block in rival_blocks))
        except ValueError:  # a law twice (coulomb[q5+q6] beside coulomb:tanh[q5+q6], one coefficient): no model
            continue
        yield indices, rival_blocks, model, _shape_starts(declared, rival_blocks, indices, shapes), alternative


@dataclass(frozen=True)
class RivalAhead:
    """A rival to fit before the chosen model is known, beside the joint refit that decides it (the first rival
    that is not the model the search adopted), and, once fitted, its fit (``None`` when the fit failed: it is then
    fitted again in turn, where its failure is told)."""

    model: IdentificationModel
    indices: tuple[int, ...]
    starts: dict[str, float]
    fit: RivalFit | None = None

    @classmethod
    def planned(cls, declared: IdentificationModel, outcome: RunnerUpOutcome, blocks: Mapping[int, Block],
                adopted: IdentificationModel) -> RivalAhead | None:
        """The first rival whose model is not ``adopted`` (the chosen model unless the joint refit drops or
        simplifies a finding), or ``None``."""
        if no_runner_up_reason(outcome) is not None:
            return None
        return next((cls(model, indices, starts) for indices, _, model, starts, _ in
                     rival_models(declared, outcome, blocks) if model_spec(model) != model_spec(adopted)), None)

    def fitted(self, fit: RivalFitter) -> RivalAhead:
        """This rival with its fit by ``fit`` (a task: it may run in another process)."""
        try:
            return replace(self, fit=fit(self.model, self.indices, self.starts))
        except (ShapeSearchError, np.linalg.LinAlgError):
            return self

    def serving(self, fit: RivalFitter) -> RivalFitter:
        """``fit``, but this rival's fit when it is asked for (the same model, indices and starts)."""
        def fitted(model: IdentificationModel, indices: tuple[int, ...], starts: dict[str, float]) -> RivalFit:
            if self.fit is not None and model_spec(model) == model_spec(self.model) and indices == self.indices \
                    and starts == self.starts:
                return self.fit
            return fit(model, indices, starts)
        return fitted


def fit_runner_up(declared: IdentificationModel, outcome: RunnerUpOutcome, blocks: Mapping[int, Block],
                  chosen: IdentificationModel, chosen_estimate: Any, fit: RivalFitter
                  ) -> tuple[RunnerUp | None, str | None]:
    """``(runner-up, None)``, or ``(None, reason)``: the best-ranked rival whose model is not ``chosen`` (the
    final model, estimated as ``chosen_estimate``), fitted by ``fit``, its BIC gap against the chosen one."""
    reason = no_runner_up_reason(outcome)
    if reason is not None:
        return None, reason
    final = tuple(blocks[item.index] for item in outcome.adopted)
    chosen_spec, failures = model_spec(chosen), []
    for indices, rival_blocks, model, starts, alternative in rival_models(declared, outcome, blocks):
        if model_spec(model) == chosen_spec:
            continue
        if len(failures) == MAX_FAILED_FITS:
            return None, f"the {MAX_FAILED_FITS} best-ranked rivals could not be fitted ({'; '.join(failures)})"
        try:
            rival = fit(model, indices, starts)
        except (ShapeSearchError, np.linalg.LinAlgError) as error:  # the data do not determine this rival: the next
            failures.append(f"{model_spec(model)}: {error}")
            continue
        p = n_parameters(model, rival.estimate)
        gap = bic_gap(channel_rss(rival.estimate), channel_rss(chosen_estimate), chosen_estimate.channel_variance,
                      _rows_count(chosen_estimate), p, n_parameters(chosen, chosen_estimate))
        return RunnerUp(model_spec(model), instead(rival_blocks, final, declared),
                        rival_effects(model, rival_blocks, rival), p, gap, outcome.last_move.gap(alternative),
                        outcome.last_move.round, rival.train_mse, rival.validation_mse, model, rival.result,
                        rival.warnings), None
    if failures:
        return None, f"no rival could be fitted ({'; '.join(failures)})"
    return None, "every rival the search fitted at its last adopted move comes out as the chosen model"


def model_spec(model: IdentificationModel) -> str:
    """A model's effects as its model file names them."""
    return ",".join(effect_spec(effect) for effect in model.effects) or "none"


def in_memory_fitter(train, validate, delay: ShapeValue | None) -> RivalFitter:
    """The in-memory diagnosis's :data:`RivalFitter`: :func:`estimation.identification.fit.identify` along the
    records moved by the chosen model's ``delay`` (``None``: none), every shape refitted from the search's."""
    def fit(model: IdentificationModel, indices: tuple[int, ...], starts: dict[str, float]) -> RivalFit:
        moved_train, moved_validate = train, validate
        if delay is not None:
            moved_train, moved_validate = delayed(train, delay.value), delayed(validate, delay.value)
        with warnings.catch_warnings():  # a rival's implausible estimates are its own: in its ``warnings``
            warnings.simplefilter("ignore", ImplausibleEstimateWarning)
            try:
                result = identify(model, moved_train, moved_validate, shape_starts=starts or None)
            except ShapeSearchError:  # the shapes ran to where the data do not determine them: keep the search's
                result = identify(model, moved_train, moved_validate, shape_starts=starts or None, shape_search=False)
        result = with_delay(result, delay)  # ShapeSearchError again: not a rival (fit_runner_up)
        shapes = [value for value in result.shapes if value is not result.delay]
        return RivalFit(result.estimate, dict(result.train.mse),
                        None if result.validation is None else dict(result.validation.mse),
                        {value.name: float(value.value) for value in shapes},
                        {value.name: float(value.std) for value in shapes}, result, tuple(result.warnings))
    return fit


def with_runner_up(diagnosis: Any, outcome: RunnerUpOutcome, blocks: Mapping[int, Block], train, validate,
                   ahead: RivalAhead | None = None) -> Any:
    """The in-memory :class:`~estimation.diagnosis.results.Diagnosis` with its runner-up (or why it has none);
    ``ahead``: a rival already fitted along the records as given (:class:`RivalAhead`), used when asked for."""
    after = diagnosis.after
    fit = in_memory_fitter(train, validate, after.delay)
    if ahead is not None and after.delay is None:
        fit = ahead.serving(fit)
    runner_up, reason = fit_runner_up(diagnosis.before.model, outcome, blocks, after.model, after.estimate, fit)
    return replace(diagnosis, runner_up=runner_up, runner_up_reason=reason)
