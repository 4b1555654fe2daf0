"""The default answer of ``oed identify`` on the streamed path: the in-memory choice among candidate models, from sums.

The in-memory identification chooses among ordinary and channel-weighted least squares and the physically
consistent fit with the robot description's bodies as prior, by their errors on a validation record of another
motion (:mod:`estimation.consistent.model_selection`, issue 34). A record over the memory budget is read in blocks
(:mod:`estimation.streaming.identification`), and every piece of that choice needs sums only:

* the unconstrained fits are solved from the training record's per-channel sums
  (:func:`~estimation.streaming.identification.identify_files_candidates`: both weightings, one covariance pass);
* the consistent fit's cost is a quadratic form in the per-channel Gram matrices ``Y_cᵀY_c`` of those sums
  (:class:`~estimation.consistent.least_squares.ConsistentLeastSquares`), and its prior's weight is chosen by the
  same rule along the same path (:func:`~estimation.consistent.identification.consistent_fit_sums`);
* each candidate's validation error comes from a ``score`` of several parameter vectors at once: from the
  validation sums when they hold the channels as recorded, else from one more pass over the validation record's
  blocks, every candidate on the same samples (the caller's);
* whether the validation record repeats the training motion is the in-memory test
  (:func:`~estimation.identification.repeated_motion.repeated_motion`) from running sums over both records read
  side by side (:func:`streamed_repeated_motion`), and whether it is a record at rest
  (:func:`~estimation.identification.repeated_motion.still_motion`) from each joint's running minimum and maximum
  over both records (:func:`streamed_still_motion`): such a record chooses nothing, as in memory.

The choice itself is the in-memory one (:func:`~estimation.consistent.model_selection.select_scored`), so that a
record gives the same answer whichever path its length sends it down.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from dynamics.models import IdentificationModel
from estimation.consistent.identification import Scorer, consistent_fit_sums
from estimation.consistent.model_selection import (
    CANDIDATES,
    CONSISTENT_FAILURES,
    Candidate,
    CandidateName,
    ConsistentSettings,
    ModelSelection,
    select_scored,
    validation_base,
    wanted_candidates,
)
from estimation.identification.repeated_motion import REPEAT_FRACTION, SAME_RATE, STILL_SHARE, still_spans_note
from estimation.streaming.chunks import read_chunks, source_step
from estimation.streaming.identification import SummedFits

__all__ = ["streamed_repeated_motion", "streamed_spans", "streamed_still_motion", "summed_selection",
           "warned_still_motion"]


def summed_selection(sums: SummedFits, *, base: Literal["ols", "wls"], given: CandidateName | None = None,
                     consistent: ConsistentSettings | None = None, score: Scorer | None = None,
                     ratio: float | None = None, still: bool = False) -> ModelSelection:
    """:func:`estimation.consistent.model_selection.select_model` of fits from sums (module docstring).

    Parameters
    ----------
    sums
        The unconstrained fits (``ols`` and ``wls``, or the one ``given``) and the sums they were solved from.
    base, given, consistent
        As :func:`~estimation.consistent.model_selection.select_model`'s.
    score
        The validation errors of several base-parameter vectors, by key, in one pass (``None``: no validation record).
    ratio
        :func:`streamed_repeated_motion` of the validation record (``None``: none).
    still
        :func:`streamed_still_motion` of the validation record: a record at rest chooses neither the weighting
        nor the answer (as in memory), its errors still listed.
    """
    settings = ConsistentSettings() if consistent is None else consistent
    fits = dict(sums.fits)
    if score is not None:  # the unconstrained candidates' errors, on the samples the others are scored on
        scored = score({name: fit.estimate.values for name, fit in fits.items()})
        fits = {name: replace(fit, validation=scored[name]) for name, fit in fits.items()}
    validated = score is not None and ratio is not None and ratio > REPEAT_FRACTION and not still
    if given is None and validated and {"ols", "wls"} <= set(fits):
        base = validation_base(fits.__getitem__, base)
    wanted = wanted_candidates(given, base, validated=score is not None)
    candidates = []
    for name in CANDIDATES:
        if name not in wanted:
            continue
        if name != "consistent":
            candidates.append(Candidate(name, fits[name]))
            continue
        try:
            refit = consistent_fit_sums(fits[base], sums.train, sums.train_errors, score,
                                        prior_weight=settings.prior_weight, prior=settings.prior,
                                        prior_source=settings.prior_source, bounds=settings.bounds)
            candidates.append(Candidate("consistent", refit))
        except CONSISTENT_FAILURES as error:
            if given == "consistent":
                raise
            candidates.append(Candidate("consistent", None, f"the consistent fit failed ({error})"))
    return select_scored(candidates, base=base, given=given, ratio=ratio, still=still)


def streamed_repeated_motion(model: IdentificationModel, train: Sequence[str | Path],
                             validation: Sequence[str | Path], *, chunk_size: int) -> float:
    """:func:`estimation.identification.repeated_motion.repeated_motion` of the records ``train`` and ``validation``
    (each its files one after the other) read block by block side by side: the largest over the joints of
    ``rms(q_val − q_train) / rms(q_train − mean)`` over the samples both records have, from running sums (the
    positions as read, on the uniform grid of a resampled file). Two single files sampled at different rates (a
    validation log the loader resampled onto a grid of another step, say) are compared as in memory: the training
    samples within the validation record's duration, the validation positions interpolated at their times from each
    record's start (:func:`_interpolated_side_by_side`)."""
    n_joints = model.robot.n_joints
    difference, total, square = np.zeros(n_joints), np.zeros(n_joints), np.zeros(n_joints)
    shift: NDArray[np.float64] | None = None
    count = 0
    if _other_rates(model, train, validation):
        pairs = _interpolated_side_by_side(_timed(model, train, chunk_size), _timed(model, validation, chunk_size))
    else:
        pairs = _side_by_side(_positions(model, train, chunk_size), _positions(model, validation, chunk_size))
    for q_train, q_validation in pairs:
        if q_train.shape[1] != q_validation.shape[1]:
            return float("inf")
        shift = q_train[0] if shift is None else shift  # sums about the first sample: no cancellation
        centred = q_train - shift
        difference += np.sum((q_validation - q_train) ** 2, axis=0)
        total += centred.sum(axis=0)
        square += np.sum(centred**2, axis=0)
        count += q_train.shape[0]
    if count == 0:
        return float("inf")
    rms_difference = np.sqrt(difference / count)
    spread = np.sqrt(np.clip(square / count - (total / count) ** 2, 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(spread > 0, rms_difference / spread, np.where(rms_difference > 0, np.inf, 0.0))
    return float(np.max(ratio))


def _other_rates(model: IdentificationModel, train: Sequence[str | Path], validation: Sequence[str | Path]) -> bool:
    """Whether the records are one file each sampled at rates that differ by more than
    :data:`~estimation.identification.repeated_motion.SAME_RATE` (the in-memory test; several files stack time
    bases that do not increase, compared sample by sample there)."""
    if len(train) != 1 or len(validation) != 1:
        return False
    step_train, step_validation = source_step(train[0], model), source_step(validation[0], model)
    if step_train is None or step_validation is None:
        return False
    return abs(step_train - step_validation) > SAME_RATE * step_train


def _timed(model: IdentificationModel, paths: Sequence[str | Path], chunk_size: int
           ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    for path in paths:
        for chunk in read_chunks(path, model, chunk_size=chunk_size):
            yield np.asarray(chunk.t, dtype=float), chunk.q


def _interpolated_side_by_side(train: Iterator[tuple[np.ndarray, np.ndarray]],
                               validation: Iterator[tuple[np.ndarray, np.ndarray]]
                               ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Blocks of the training positions within the validation record's duration and the validation positions
    linearly interpolated at their times from each record's start (as
    :func:`estimation.identification.repeated_motion.repeated_motion` aligns records of other rates), holding a
    few blocks of the validation record at a time."""
    held_t, held_q = np.empty(0), None
    start_train = start_validation = None
    exhausted = False
    for t, q in train:
        if t.shape[0] == 0:
            continue
        start_train = t[0] if start_train is None else start_train
        elapsed = t - start_train
        while not exhausted and (held_q is None or held_t[-1] < elapsed[-1]):
            block = next(validation, None)
            if block is None:
                exhausted = True
                break
            t_v, q_v = block
            if t_v.shape[0] == 0:
                continue
            start_validation = t_v[0] if start_validation is None else start_validation
            held_t = np.concatenate([held_t, t_v - start_validation])
            held_q = q_v if held_q is None else np.vstack([held_q, q_v])
        if held_q is None:
            return
        if held_q.shape[1] != q.shape[1]:
            yield q, held_q[:0]
            return
        inside = elapsed <= held_t[-1]
        if np.any(inside):
            yield q[inside], np.column_stack([np.interp(elapsed[inside], held_t, column) for column in held_q.T])
        if not np.all(inside) and exhausted:
            return
        keep = max(int(np.searchsorted(held_t, elapsed[-1], side="right")) - 1, 0)  # the sample at or before
        held_t, held_q = held_t[keep:], held_q[keep:]


def streamed_spans(model: IdentificationModel, paths: Sequence[str | Path], *,
                   chunk_size: int) -> NDArray[np.float64] | None:
    """Each joint's span (max − min) of the positions over the files ``paths`` read block by block (as
    :func:`streamed_repeated_motion` reads them), ``None`` when they hold no rows."""
    low: NDArray[np.float64] | None = None
    high: NDArray[np.float64] | None = None
    for q in _positions(model, paths, chunk_size):
        if q.shape[0] == 0:
            continue
        low = q.min(axis=0) if low is None else np.minimum(low, q.min(axis=0))
        high = q.max(axis=0) if high is None else np.maximum(high, q.max(axis=0))
    return None if low is None or high is None else high - low


def streamed_still_motion(model: IdentificationModel, train: Sequence[str | Path], validation: Sequence[str | Path],
                          *, chunk_size: int) -> tuple[bool, NDArray[np.float64] | None, NDArray[np.float64] | None]:
    """:func:`estimation.identification.repeated_motion.still_motion` of the records ``train`` and ``validation``
    (each its files one after the other) in bounded memory: whether every joint of the validation record spans
    less than :data:`~estimation.identification.repeated_motion.STILL_SHARE` of its range in training, with the
    two records' spans (:func:`streamed_spans`; ``None``: no rows)."""
    moved = streamed_spans(model, train, chunk_size=chunk_size)
    held = streamed_spans(model, validation, chunk_size=chunk_size)
    if moved is None or held is None or moved.shape != held.shape:
        return False, moved, held
    return bool(np.all(held < STILL_SHARE * moved)), moved, held


def warned_still_motion(model: IdentificationModel, train: Sequence[str | Path], validation: Sequence[str | Path],
                        *, chunk_size: int) -> bool:
    """:func:`streamed_still_motion`, warned as in memory (:func:`~estimation.identification.repeated_motion.
    still_spans_note`) when the validation record is at rest: it then chooses nothing. The files' own findings are
    not said again (the passes that fit them say them)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        still, moved, held = streamed_still_motion(model, train, validation, chunk_size=chunk_size)
    if still and moved is not None and held is not None:
        note = still_spans_note(moved, held)
        if note is not None:
            warnings.warn(note, stacklevel=2)
    return still


def _positions(model: IdentificationModel, paths: Sequence[str | Path], chunk_size: int) -> Iterator[np.ndarray]:
    for path in paths:
        for chunk in read_chunks(path, model, chunk_size=chunk_size):
            yield chunk.q


def _side_by_side(first: Iterator[np.ndarray], second: Iterator[np.ndarray]
                  ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Blocks of the same rows of two streams of row blocks, until either ends."""
    left = right = np.empty((0, 0))
    while True:
        while left.shape[0] == 0:
            left = next(first, None)
            if left is None:
                return
        while right.shape[0] == 0:
            right = next(second, None)
            if right is None:
                return
        rows = min(left.shape[0], right.shape[0])
        yield left[:rows], right[:rows]
        left, right = left[rows:], right[rows:]
