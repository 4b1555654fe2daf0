"""One model per result file (issue 34): the answer ``result.json`` and ``report.json`` give is the model the verb
chose (:mod:`estimation.consistent.model_selection`), the one ``oed predict`` uses and ``oed export`` writes.

:class:`ChosenModel` is that model's parameters (with their standard deviations) and its errors on the training and
validation records, whichever kind of fit it is: an unconstrained least-squares fit
(:class:`~estimation.identification.fit.IdentificationResult`) or the physically consistent refit
(:class:`~estimation.consistent.identification.ConsistentResult`). :func:`answer_identification` makes
``result.json``'s top level that model's (``parameters``, ``train``, ``validation``, ``cov_method``, ``hac_lags``,
``model_parameters``), adding ``chosen`` (its name) and ``train.model``, ``validation.model``;
:func:`answer_diagnosis` adds ``train.chosen`` and ``validation.chosen`` to ``report.json`` beside the diagnosis's
``before`` and ``after`` (as ``test.chosen``), and makes ``model_parameters`` the chosen model's. The other
candidates' errors stay in ``model_selection.candidates`` and their models in ``model_file.alternatives``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from estimation.consistent.identification import ConsistentResult
from estimation.consistent.model_selection import ModelSelection
from estimation.identification.fit import IdentificationResult
from estimation.identification.validation import Comparison
from estimation.uncertainty.noise_floor import NoiseFloor

__all__ = ["ChosenModel", "alternative_warnings", "answer_diagnosis", "answer_identification", "chosen_messages",
           "mse_line"]


@dataclass(frozen=True)
class ChosenModel:
    """The model a verb chose: its name, base parameters and errors.

    Attributes
    ----------
    name
        ``ols``, ``wls``, ``consistent`` (:data:`estimation.consistent.model_selection.CANDIDATES`).
    fit
        Its :class:`IdentificationResult` or :class:`ConsistentResult`.
    """

    name: str
    fit: IdentificationResult | ConsistentResult

    @classmethod
    def of(cls, selection: ModelSelection) -> ChosenModel:
        """The chosen candidate of ``selection``."""
        fit = selection.chosen_candidate.fit
        if fit is None:
            raise ValueError(f"the chosen candidate {selection.chosen!r} was not fitted")
        return cls(selection.chosen, fit)

    @property
    def consistent(self) -> bool:
        return isinstance(self.fit, ConsistentResult)

    @property
    def train(self) -> Comparison:
        return self.fit.train

    @property
    def validation(self) -> Comparison | None:
        return self.fit.validation

    @property
    def values(self) -> np.ndarray:
        return np.asarray(self.fit.estimate.values, dtype=float)

    @property
    def std(self) -> np.ndarray:
        return np.asarray(self.fit.estimate.std, dtype=float)

    @property
    def cov_method(self) -> str:
        """How the standard deviations were computed: the least-squares fit's covariance (``hac``, ``batch_means``,
        ``classical``), or the consistent fit's ``reduced Hessian``."""
        estimate = self.fit.estimate
        return estimate.uncertainty_method if self.consistent else estimate.cov_method

    @property
    def hac_lags(self) -> int | None:
        return None if self.consistent else self.fit.estimate.hac_lags

    @property
    def warnings(self) -> tuple[str, ...]:
        """The model's own warnings: an unconstrained fit's implausible estimates, or those the consistent fit
        holds at or above zero (:attr:`~estimation.consistent.identification.ConsistentResult.warnings`)."""
        return tuple(self.fit.warnings)

    @property
    def shapes(self) -> tuple[Any, ...]:
        """The shape parameters (and the delay) of its laws: an unconstrained fit's, or those the consistent fit
        holds at the unconstrained fit's values (:class:`~estimation.identification.shaped.ShapeValue`)."""
        return tuple((self.fit.unconstrained if self.consistent else self.fit).shapes)

    @property
    def shape_std(self) -> dict[str, float | None]:
        """The shapes' standard deviations by name: an unconstrained fit's; ``None`` each for the consistent fit,
        which holds them fixed (not estimated: its model file's ``shape_std`` is empty)."""
        return {value.name: None if self.consistent else float(value.std) for value in self.shapes}

    def records(self) -> list[dict[str, Any]]:
        """One dict a base parameter: ``name, expression, value, std, relative_std`` (in %; ``None`` at a value of
        exactly 0 or a standard deviation that is not finite)."""
        estimate = self.fit.estimate
        records = []
        for name, expression, value, std in zip(estimate.names, estimate.expressions, self.values, self.std):
            relative = 100.0 * std / abs(value) if value != 0 and np.isfinite(std) else None
            records.append({"name": name, "expression": expression, "value": float(value),
                            "std": float(std) if np.isfinite(std) else None, "relative_std": relative})
        return records

    def parameter_lines(self) -> list[str]:
        """One line a base parameter: value, standard deviation and relative standard deviation."""
        records = self.records()
        width = max(len(record["name"]) for record in records)
        return [f"  {r['name']:<{width}}  {r['value']:+.5g} ± {_number(r['std'], '.2g')}  "
                f"({_number(r['relative_std'], '.3g')} %)" for r in records]


def alternative_warnings(selection: ModelSelection) -> dict[str, tuple[str, ...]]:
    """The warnings of the fitted candidates not chosen (an unconstrained fit's implausible estimates) that are not
    the chosen model's, by name (those with none left out): said beside those candidates, not as the answer's."""
    chosen = ChosenModel.of(selection)
    found = {candidate.name: tuple(text for text in getattr(candidate.fit, "warnings", ()) if text not in chosen.warnings)
             for candidate in selection.alternatives}
    return {name: texts for name, texts in found.items() if texts}


def chosen_messages(messages: Sequence[str], selection: ModelSelection | None) -> list[str]:
    """``messages`` (the warnings caught while fitting) without the other candidates' own
    (:func:`alternative_warnings`), and with the chosen model's own (the consistent fit's are not issued as
    warnings): what is said of the result is said of the chosen model."""
    if selection is None:
        return list(messages)
    others = {text for texts in alternative_warnings(selection).values() for text in texts}
    kept = [text for text in messages if text not in others]
    return [*kept, *(text for text in ChosenModel.of(selection).warnings if text not in kept)]


def _number(value: float | None, form: str) -> str:
    return "nan" if value is None else format(value, form)


def mse_line(label: str, mse: Mapping[str, float]) -> str:
    """``label: tau1 0.04445  tau2 …``: a line of errors per channel, as the summaries print them."""
    return f"{label}: " + "  ".join(f"{channel} {value:.4g}" for channel, value in mse.items())


def floor_ratios(mse: Mapping[str, float], floor: NoiseFloor | None) -> dict[str, float] | None:
    """Each channel's MSE over its noise floor (``None`` without a floor)."""
    if floor is None:
        return None
    floors = floor.mse()
    return {channel: (value / floors[channel] if floors[channel] > 0 else float("inf"))
            for channel, value in mse.items() if channel in floors} or None


def answer_identification(document: dict[str, Any], chosen: ChosenModel, *,
                          floor: NoiseFloor | None = None, fitted: IdentificationResult | None = None) -> None:
    """Make ``result.json``'s top level (``document``, in place) the chosen model's: ``parameters``, ``train``,
    ``validation`` (its ``mse``, ``mse_filtered`` and ``mse_over_floor``; the trivial predictors' errors kept),
    ``cov_method``, ``hac_lags``, ``model_parameters.values``/``std``, ``shape_std`` and
    ``model_parameters.shape_std`` (``null`` each for shapes the consistent fit held), ``delay.std`` (``null`` when
    held), ``warnings`` (the chosen model's own in place of those of ``fitted``, the unconstrained fit ``document``
    was made from: these stay in ``model_file.alternatives``); add ``chosen``, ``train.model``,
    ``validation.model`` and ``model_parameters.chosen`` (its name). ``method``, ``cond`` and ``channel_std``
    stay: the consistent fit is the unconstrained fit's weighting of the same regressor. ``floor``: the validation
    record's noise floor."""
    document["chosen"] = chosen.name
    document["parameters"] = chosen.records()
    document["cov_method"], document["hac_lags"] = chosen.cov_method, chosen.hac_lags
    if fitted is not None:  # the fit's own warnings first (IdentificationResult.to_dict), the run's after them
        others = set(fitted.warnings) - set(chosen.warnings)
        kept = [text for text in document.get("warnings", []) if text not in others]
        document["warnings"] = [*(text for text in chosen.warnings if text not in kept), *kept]
    if "shape_std" in document:
        document["shape_std"] = chosen.shape_std
    if document.get("delay") is not None and chosen.consistent:
        document["delay"] = {**document["delay"], "std": None}  # held at the unconstrained fit's value
    document["train"] = {**chosen.train.to_dict(), "model": chosen.name}
    if chosen.validation is not None and document.get("validation") is not None:
        kept = {key: value for key, value in document["validation"].items() if key in ("zero_mse", "nominal_mse")}
        document["validation"] = {**chosen.validation.to_dict(), **kept, "model": chosen.name}
        if floor is not None:
            document["validation"]["mse_over_floor"] = floor_ratios(chosen.validation.mse, floor)
    _answer_parameters(document, chosen)


def answer_diagnosis(document: dict[str, Any], chosen: ChosenModel, *, floor: NoiseFloor | None = None) -> None:
    """Add the chosen model's errors to ``report.json`` (``document``, in place) beside the diagnosis's ``before``
    and ``after``: ``train.chosen: {name, mse}`` and ``validation.chosen: {name, mse[, mse_over_floor]}``, and its
    own warnings as ``warnings.chosen``; make ``model_parameters`` the chosen model's (``model_parameters.chosen``
    its name)."""
    document["train"]["chosen"] = {"name": chosen.name, "mse": dict(chosen.train.mse)}
    document["warnings"]["chosen"] = list(chosen.warnings)
    if chosen.validation is not None:
        document["validation"]["chosen"] = {"name": chosen.name, "mse": dict(chosen.validation.mse)}
        ratios = floor_ratios(chosen.validation.mse, floor)
        if ratios is not None:
            document["validation"]["chosen"]["mse_over_floor"] = ratios
    _answer_parameters(document, chosen)


def _answer_parameters(document: dict[str, Any], chosen: ChosenModel) -> None:
    parameters = document.get("model_parameters")
    if parameters is None:
        return
    if list(parameters["names"]) != list(chosen.fit.estimate.names):
        raise ValueError("the chosen model's base parameters are not those of model_parameters")
    parameters["values"] = [float(value) for value in chosen.values]
    parameters["std"] = [float(value) if np.isfinite(value) else None for value in chosen.std]
    if parameters.get("shape_std"):
        parameters["shape_std"] = chosen.shape_std
    parameters["chosen"] = chosen.name
