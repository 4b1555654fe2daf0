"""The channel weighting of an identification chosen by held-out evidence: channel-weighted or ordinary least squares.

The PUMA paper weights each channel by the inverse of its residual variance (eq. 20, iterated:
:class:`~estimation.estimators.least_squares.WeightedLeastSquares`). That is the efficient estimate when every
channel's residual is its noise. When a channel's residual is mostly what the model lacks, its variance is large,
its weight small, and the fit gives that channel up: on a real Schunk LWA 4P the weighted fit was 3 times worse
than ordinary least squares on joint 3 and 1.5 times worse in all. Which weighting predicts better is a question
the data answer: both are fitted on ``folds - 1`` contiguous blocks of the training record and predict the last
(the channels as recorded), as :class:`estimation.identification.preprocessing_choice.HeldOutScore` does for the
derivatives, and scored by the geometric mean over channels of the held-out MSE. The weighted fit stays unless
ordinary least squares is clearly better (:data:`~estimation.identification.preprocessing_choice.CLEARLY_BETTER`).

A block whose others do not determine every parameter (a joint that reverses only inside that block: its Coulomb
and offset columns are one elsewhere) cannot be predicted by either weighting: it is left unscored for both, so that
both are scored on the same samples, and said (:class:`HeldOutBlocksWarning`); the whole record may still determine
the model. With no block scored the weighted fit stays, for want of evidence. The choice is the toolkit's own: it
never ends the run (issue 34).

A record longer than :data:`~estimation.identification.preprocessing_choice.SCORED_SAMPLES` samples is scored on the
window its derivatives were chosen on, prepared by the plan chosen (:func:`weighting_samples`): the samples a
streamed identification reads too, so that both paths choose alike.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from dynamics.runtime.threads import single_threaded_blas
from estimation.estimators.identification_problem import IdentificationProblem, ResidualBand, stack
from estimation.estimators.least_squares import IdentifiabilityError, LeastSquares, WeightedLeastSquares
from estimation.identification.preprocessing_choice import (
    CLEARLY_BETTER,
    ChoiceWindow,
    blocked_folds,
    geometric_mean,
    thinned,
)
from estimation.preprocessing.plan import Preprocessing, prepare

__all__ = ["HeldOutBlocksWarning", "WeightingChoice", "choose_weighting", "weighting_samples"]

Weighting = Literal["wls", "ols"]


class HeldOutBlocksWarning(UserWarning):
    """Blocks of the training record left unscored by the weighting choice: the other blocks do not determine every
    parameter (module docstring)."""


@dataclass(frozen=True)
class WeightingChoice:
    """The weighting chosen and each one's held-out error.

    Attributes
    ----------
    method
        ``wls`` or ``ols``.
    scores
        Geometric mean over channels of the held-out MSE, per weighting.
    held_out_mse
        Per weighting, ``{channel: held-out MSE}``.
    folds
        Blocks of the training record, each held out once.
    unscored
        The blocks (numbered from 1) left unscored for every weighting: the other blocks do not determine every
        parameter; ``note`` says which.
    note
        Why those blocks are unscored (the parameters not determined), or ``""``.
    """

    method: Weighting
    scores: dict[str, float]
    held_out_mse: dict[str, dict[str, float]]
    folds: int
    unscored: tuple[int, ...] = ()
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        """``{selection: "held-out", chosen, folds, candidates: {wls: {score, held_out_mse}, ols: {…}}}``, and
        ``unscored_blocks`` with its ``note`` when blocks were left unscored."""
        document: dict[str, Any] = {
            "selection": "held-out", "chosen": self.method, "folds": self.folds,
            "candidates": {name: {"score": self.scores[name], "held_out_mse": self.held_out_mse[name]}
                           for name in self.scores}}
        if self.unscored:
            document.update(unscored_blocks=list(self.unscored), note=self.note)
        return document


@single_threaded_blas()
def choose_weighting(model: IdentificationModel, train: Measurements, *, folds: int = 5,
                     max_rows: int = 6000) -> WeightingChoice:
    """Channel-weighted or ordinary least squares for ``model`` on the prepared ``train`` (module docstring)."""
    if int(folds) != folds or folds < 2:
        raise ValueError(f"folds must be an integer of at least 2, got {folds}")
    problem = stack(model, thinned(train.as_recorded, max_rows))
    squares = {name: held_out_squares(problem, estimator, folds)
               for name, estimator in (("wls", WeightedLeastSquares), ("ols", LeastSquares))}
    unscored = {number: lacking for blocks in squares.values() for number, lacking in enumerate(blocks, start=1)
                if isinstance(lacking, str)}
    note = ""
    if unscored:
        note = (f"the weighting's held-out block(s) {', '.join(map(str, sorted(unscored)))} of {int(folds)} left "
                f"unscored for both weightings (the other blocks do not determine "
                f"{'; '.join(dict.fromkeys(unscored.values()))}); the whole record is fitted"
                + ("" if len(unscored) < folds else "; no block scored: the weighted fit stays, for want of "
                   "evidence"))
        warnings.warn(note, HeldOutBlocksWarning, stacklevel=2)
    if len(unscored) == folds:
        return WeightingChoice("wls", {}, {}, int(folds), tuple(sorted(unscored)), note)
    errors = {}
    for name, blocks in squares.items():
        scored = [block for number, block in enumerate(blocks, start=1) if number not in unscored]
        errors[name] = sum(squared for squared, _ in scored) / sum(count for _, count in scored)
    scores = {name: geometric_mean(mse) for name, mse in errors.items()}
    method: Weighting = "ols" if scores["ols"] < CLEARLY_BETTER * scores["wls"] else "wls"
    return WeightingChoice(method, scores, {name: dict(zip(problem.channels, map(float, mse)))
                                            for name, mse in errors.items()}, int(folds),
                           tuple(sorted(unscored)), note)


def held_out_squares(problem: IdentificationProblem, estimator: type[LeastSquares],
                     folds: int) -> list[tuple[NDArray[np.float64], int] | str]:
    """Per contiguous block, predicted by ``estimator`` fitted on the others: the sum of squared errors per channel
    and the block's samples, or, where the others do not determine every parameter, the parameters they lack."""
    blocks: list[tuple[NDArray[np.float64], int] | str] = []
    for held, kept in blocked_folds(problem.n_samples, folds):
        part = IdentificationProblem(problem.Y[kept], problem.y[kept], problem.channels, problem.names,
                                     problem.expressions, band=_kept_band(problem, held), passive=problem.passive,
                                     mask=None if problem.mask is None else problem.mask[kept])
        try:
            theta = estimator().fit(part).theta_
        except IdentifiabilityError as error:
            blocks.append(str(error).split(": the regressor")[0].removeprefix("the data do not determine "))
            continue
        # a masked equation's residual is 0 (Y and y zeroed): each channel's block counts its valid samples
        blocks.append((np.sum((problem.y[held] - problem.Y[held] @ theta) ** 2, axis=0),
                       held.stop - held.start if problem.mask is None else np.sum(problem.mask[held], axis=0)))
    return blocks


def _kept_band(problem: IdentificationProblem, held: slice) -> ResidualBand | None:
    """The problem's band on the samples left when ``held`` is taken out: each segment's remainder filtered on its
    own (the held block joins no two stretches)."""
    if problem.band is None:
        return None
    bounds, rates, removed = [], [], held.stop - held.start
    for start, stop, band in problem.band.pieces(problem.n_samples):  # each segment at its rate
        for lower, upper in ((start, min(stop, held.start)), (max(start, held.stop), stop)):
            if upper > lower:
                shift = removed if lower >= held.stop else 0
                bounds.append((lower - shift, upper - shift))
                rates.append(band.rate_hz)
    return replace(problem.band, segments=tuple(bounds), rates=tuple(rates) if len(set(rates)) > 1 else ())


def weighting_samples(window: ChoiceWindow, plan: Preprocessing, prepared: Measurements | None = None) -> Measurements:
    """The samples the weighting is chosen on: ``prepared`` (the whole training record, as prepared) when given
    and the window is the whole record, else the window prepared by ``plan`` (module docstring)."""
    if prepared is not None and window.whole:
        return prepared
    return prepare(window.segments, plan, role="training data")
