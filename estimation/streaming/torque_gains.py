"""An unknown gain on each joint's recorded torque, a candidate of the streamed default answer
(:mod:`estimation.consistent.torque_gains` on files read in blocks).

The gains are fitted from the training sums the streamed identification already holds (the per-channel Gram
matrices ``G_j``, moments ``b_j`` and powers ``c_j`` of the base regressor: Gauss-Newton on channel sums is the
in-memory method, :func:`~estimation.consistent.torque_gains.gains_from_sums`). The check on the validation record
(:func:`~estimation.consistent.torque_gains.gains_checked`) needs the squared errors of the fits with and without the
gains summed over 40, 20 and 10 contiguous blocks of the record as recorded: one pass over the validation files
(:func:`streamed_gains_check`; memory: one chunk and ``3 x 40`` sums a channel). When the check takes them, the
answer's candidates are chosen again from the sums of the torques divided by the gains, which are the declared
model's sums with each channel's moments over its gain and its powers over its gain squared (:func:`divided_sums`:
no pass), scored in the log's units (:class:`GainsScorer`: the gains times the model's torques against the channels
as recorded, one pass over the validation files a call).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dynamics.models import IdentificationModel
from estimation.data.channel_mask import masked_rows
from estimation.data.passive import passive_channels
from estimation.consistent.torque_gains import (SIGNIFICANCE_BLOCKS, TorqueGains, block_labels, channel_factors,
                                                gains_checked, gains_from_sums)
from estimation.estimators.normal_equations import NormalEquations
from estimation.estimators.summed_least_squares import SummedLeastSquares
from estimation.identification.validation import ChannelErrors
from estimation.streaming.cluster import sum_files
from estimation.streaming.identification import SummedFits
from estimation.streaming.periods import plan_chunks
from estimation.streaming.block_errors import BlockSquares
from estimation.streaming.recorded_errors import counted_predicted_errors

__all__ = ["GainsScorer", "divided_sums", "files_gains_check", "streamed_gains_check"]


def streamed_gains_check(model: IdentificationModel, train: NormalEquations, paths: Sequence[str | Path],
                         n_validation: int, options: Mapping[str, Any]) -> tuple[TorqueGains, bool, str] | None:
    """:func:`~estimation.consistent.torque_gains.gains_on_validation` of files read in blocks: the gains from the
    training sums ``train`` and the check on the validation files ``paths`` (``n_validation`` samples as recorded;
    ``options``: how they were read and prepared, :func:`estimation.streaming.periods.plan_chunks`'s), in one pass.
    ``None`` when the pass does not read ``n_validation`` samples (the blocks would not be the record's), or for a
    model with a passive joint's channel (its zero has no gain)."""
    if passive_channels(model):
        return None
    fitted = gains_from_sums(model, (np.asarray(train.gram), np.asarray(train.moment), np.asarray(train.power)),
                             int(train.n_samples))
    if isinstance(fitted[1], str):
        return fitted[0], False, fitted[1]
    gains, theta, plain = fitted
    m = model.n_channels
    labels = {count: block_labels(n_validation, count) for count in SIGNIFICANCE_BLOCKS}
    sums = {count: (np.zeros((count, m)), np.zeros((count, m))) for count in SIGNIFICANCE_BLOCKS}
    left_out = {count: np.zeros(count, dtype=np.int64) for count in SIGNIFICANCE_BLOCKS}  # masked rows, per block
    seen = 0
    for path in paths:
        for chunk in plan_chunks(str(path), model, as_recorded=True, **options):
            record = chunk.as_recorded
            measured = record.channels(model.channels)
            if seen + measured.shape[0] > n_validation:
                return None
            squared = ((measured - model.predict(plain, record.q, record.dq, record.ddq)) ** 2,
                       (measured - gains.values * model.predict(theta, record.q, record.dq, record.ddq)) ** 2)
            masked = masked_rows(measured)  # a sample with a masked channel left out whole, as memory's check
            if masked is not None:
                squared = tuple(np.where(masked[:, None], 0.0, values) for values in squared)
            for count, (declared, with_gains) in sums.items():
                where = labels[count][seen:seen + measured.shape[0]]
                np.add.at(declared, where, squared[0])
                np.add.at(with_gains, where, squared[1])
                if masked is not None:
                    np.add.at(left_out[count], where[masked], 1)
            seen += measured.shape[0]
    if seen != n_validation:
        return None
    blocks = {count: (*sums[count], np.bincount(labels[count], minlength=count) - left_out[count])
              for count in SIGNIFICANCE_BLOCKS}
    return (gains, *gains_checked(gains, model.channels, blocks))


def files_gains_check(model: IdentificationModel, paths: Sequence[str | Path], validate: Sequence[str | Path],
                      options: Mapping[str, Any], executor: Any = None) -> tuple[TorqueGains, bool, str] | None:
    """:func:`streamed_gains_check` of ``model`` on training files ``paths`` and validation files ``validate``, read
    with ``options`` (:func:`~estimation.streaming.cluster.sum_files`'s: ``chunk_size``, ``cutoff_hz``,
    ``decimation``, ``held_torques``; ``frequency_hz``, ``harmonics``: the Fourier path): the sums of the training files and the count of the validation files' samples
    in one pass each, then the check's pass (as the in-memory diagnosis measures them on the prepared records,
    :func:`~estimation.consistent.torque_gains.gains_for_records`, of the plain model it passes). Memory: the sums
    (``m p²`` floats) and one chunk."""
    train, _ = sum_files(model, paths, executor=executor, **options)
    validation, parts = sum_files(model, validate, executor=executor, **options)
    # the samples the check's pass reads: on the Fourier path (the sums hold averaged periods) every recorded row
    count = sum(int(part.rows) for part in parts) if options.get("frequency_hz") is not None \
        else int(validation.n_samples)
    return streamed_gains_check(model, train, validate, count, options)


def _divided(sums: NormalEquations | None, factors: NDArray[np.float64]) -> NormalEquations | None:
    """``sums`` of the same regressor with each channel's target divided by its factor: the moments over it, the
    powers over its square, the last column of the TSQR factor over it (``[Y | y/g] = [Y | y] diag(1, …, 1/g)``)."""
    if sums is None:
        return None
    factor = np.array(sums.factor)
    factor[:, :, -1] /= factors[:, None]
    return replace(sums, moment=np.asarray(sums.moment) / factors[:, None], power=np.asarray(sums.power) / factors**2,
                   factor=factor, band=_divided(sums.band, factors))


def divided_sums(sums: SummedFits, gains: TorqueGains, methods: Sequence[str]) -> SummedFits:
    """The streamed identification's sums with the torques divided by ``gains`` (:func:`_divided`; the files' own
    sums too) and its unconstrained fits of ``methods`` solved again from them, their errors from those sums (the
    model's units; the answer is scored in the log's by :class:`GainsScorer`)."""
    factors = channel_factors(gains, sums.train.channels)
    train, validation = _divided(sums.train, factors), _divided(sums.validation, factors)
    files = tuple(replace(part, sums=_divided(part.sums, factors)) for part in sums.files)
    validation_files = tuple(replace(part, sums=_divided(part.sums, factors)) for part in sums.validation_files)
    divided = SummedFits({}, train, validation, files, validation_files)
    for name in methods:
        fit = sums.fits[name]
        estimate = SummedLeastSquares(method=name).fit(train).estimate_
        divided.fits[name] = replace(fit, estimate=estimate, train=divided.train_errors(estimate.values),
                                     validation=None if validation is None else divided.validation_errors(
                                         estimate.values))
    return divided


def _scaled_prediction(model: IdentificationModel, theta: NDArray[np.float64], factors: NDArray[np.float64],
                       q: NDArray[np.float64], dq: NDArray[np.float64], ddq: NDArray[np.float64]) -> NDArray[np.float64]:
    return model.predict(theta, q, dq, ddq) * factors


class GainsScorer:
    """The validation errors of base-parameter vectors of the model fitted to the torques divided by ``gains``, in
    the log's units: the gains times its torques against the channels as recorded, one pass over the validation files
    ``paths`` (read with ``options``) a call (:data:`estimation.consistent.identification.Scorer`). ``n_samples``:
    the samples that pass gives (the validation sums'), when known: each error then carries the MSE of each
    validation block (:class:`estimation.streaming.block_errors.BlockSquares`, for the paired difference of the
    answer's candidates, as memory reports it)."""

    def __init__(self, model: IdentificationModel, gains: TorqueGains, paths: Sequence[str | Path],
                 options: Mapping[str, Any], n_samples: int | None = None) -> None:
        self.model, self.paths, self.options = model, [str(path) for path in paths], dict(options)
        self.factors = channel_factors(gains, model.channels)
        self.n_samples = n_samples

    def __call__(self, thetas: Mapping[Any, NDArray[np.float64]]) -> dict[Any, ChannelErrors]:
        predictors = {key: functools.partial(_scaled_prediction, self.model, np.asarray(theta, dtype=float),
                                             self.factors) for key, theta in thetas.items()}
        blocks = None if self.n_samples is None else {key: BlockSquares(self.n_samples, self.model.n_channels)
                                                      for key in thetas}
        errors, count = counted_predicted_errors(self.model, predictors, self.paths, blocks=blocks, **self.options)
        return {key: ChannelErrors(errors[key], count,
                                   block_mse=None if blocks is None else blocks[key].block_mse(self.model.channels))
                for key in thetas}
