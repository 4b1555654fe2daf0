"""Identification of one estimate from many records in bounded memory (``oed identify --chunk-size``).

::

    result = identify_files(model, ["run1.csv", "run2.parquet"], ["check.csv"], chunk_size=10_000,
                            cutoff_hz=5.0, executor=client.get_executor())
    result.to_dict()   # the ``oed identify`` document (the in-memory IdentificationResult, same keys), with its
                       # ``streaming`` block and ``identification_path: "streamed"``

The result is the in-memory path's :class:`~estimation.identification.fit.IdentificationResult` (``path="streamed"``):
its estimate a :class:`~estimation.estimators.summed_least_squares.SummedEstimate`, its training and validation
errors :class:`~estimation.identification.validation.ChannelErrors` (no samples held), what the sums cannot give
in ``not_computed`` and how the files were read in ``streaming``.

The training files reduce to one :class:`~estimation.estimators.normal_equations.NormalEquations`
(:func:`estimation.streaming.cluster.sum_files`), the estimator solves from it
(:class:`~estimation.estimators.normal_equations.SummedLeastSquares`, the same iterated channel weighting as
:class:`~estimation.estimators.least_squares.WeightedLeastSquares`), and the MSEs per channel are sums too:
``‖y_c − Y_c θ̂‖² / N`` from the training sums and from the validation files' own sums.

The standard deviations (``covariance="hac"``, the default, as the in-memory ``identify``) are the
batch-means sandwich (``cov_method: "batch_means"``): they hold when the residuals are correlated
in time (the filter path's derivative errors, an effect the model lacks), where the classical ones
of the sums are far too small. They need the residuals at the final estimate, hence a **third
pass** over the training files (the first reads, the second is the solve's; here: read and prepare
again, score: :func:`batch_means_covariance` below), through the same executor,
one task a file, in bounded memory. It costs about what summing cost: measured on the 7-joint KUKA,
filter path, 1 M samples, serial, chunks of 10 000, the covariance pass took 8.3 s of a 17.7 s run
(47 %; the sums pass 6.3 s; ``streaming.seconds``, ``benchmarks/bench_streaming.py``).
``covariance="classical"`` skips it (white residuals assumed).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from dynamics.runtime.progress import step
from dynamics.runtime.threads import single_threaded_blas
from estimation.data.passive import passive_channels
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE, NormalEquations
from estimation.estimators.summed_least_squares import SummedLeastSquares
from estimation.identification.fit import IdentificationResult, ImplausibleEstimateWarning, implausible_estimates
from estimation.identification.subtracted_load import SubtractedLoad
from estimation.identification.validation import ChannelErrors
from estimation.streaming.chunks import (FileScans, FileSums, StreamingUnsupportedError, automatic_cutoff, read_chunks)
from estimation.streaming.cluster import (IncompleteSumError, caught_warnings, file_stamp, model_from_payload,
                                          model_payload, sum_files)
from estimation.streaming.covariance import BatchScores, chunk_scores, sandwich
from estimation.streaming.diagnosis_passes import map_files
from estimation.streaming.diagnosis_sums import ColumnLayout
from estimation.streaming.periods import plan_chunks

#: the standard deviations: batch means from a third pass (``"hac"``) or white residuals assumed
StreamedCovariance = Literal["hac", "classical"]


#: what the streamed identification cannot compute, by the ``oed identify`` document's key
#: (:attr:`~estimation.identification.fit.IdentificationResult.not_computed`)
STREAMED_NOT_COMPUTED = {
    "hac_lags": "the standard deviations are not HAC ones: batch means from a pass over the files (cov_method; "
                "their batch length in streaming.covariance), or classical",
    "consistent": "the physically consistent refit is made in memory (--consistent refits in memory)",
    "links": "the bodies of the physically consistent refit are had in memory",
    "model_selection": "the choice among ols, wls and the consistent refit by their validation errors is made in "
                       "memory; streamed, the model is the weighting asked for or chosen on held-out blocks "
                       "(method_selection)",
    "gravity": "the fit with the found gravity (or none) is a candidate of the answer chosen from sums "
               "(estimation.consistent.mounted_gravity) by oed identify, as in memory, not by identify_files",
    "subtracted": "the fit to the torques with the description's gravity torque added back (a log less that load) "
                  "is a candidate of the answer chosen from sums (estimation.consistent.mounted_gravity) by oed "
                  "identify, as in memory, not by identify_files",
    "saturated_samples": "a torque or wrench sensor past its range (a channel held at its extreme while the robot moves) is "
                         "said streamed (SaturatedTorqueWarning: the whole record judged block by block, as in memory) "
                         "and its samples are left out of the streamed sums and errors as in memory (masked in that "
                         "channel only); the counts per record and segment are said in the warning, not collected "
                         "by identify_files (oed identify counts them: estimation.streaming.masked_counts)",
}


def streaming_record(*, chunk_size: int, cutoff_hz: float | None, frequency_hz: float | None,
                     files: Sequence[FileSums], validation_files: Sequence[FileSums], cov_method: str,
                     batch_length: int | None, classical_std: dict[str, float] | None,
                     seconds: dict[str, float]) -> dict[str, Any]:
    """The document's ``streaming``::

        streaming: {chunk_size, cutoff_hz, frequency_hz, files: [{path, rows, samples, decimation, margin,
                    periods_averaged, resampled_from}], validation_files: [...],
                    covariance: {method, batch_length, classical_std: {name: std}}, seconds: {...}}

    ``rows``: samples read (on the uniform grid when the file was resampled from ``resampled_from`` rows);
    ``samples``: samples summed (after averaging or decimation).
    """
    return {
        "chunk_size": chunk_size,
        "cutoff_hz": cutoff_hz,
        "frequency_hz": frequency_hz,
        "files": [_file_record(part) for part in files],
        "validation_files": [_file_record(part) for part in validation_files],
        "covariance": {"method": cov_method, "batch_length": batch_length, "classical_std": classical_std},
        "seconds": dict(seconds),
    }


def summed_errors(mse: dict[str, float], n_samples: int, parts: Sequence[FileSums]) -> ChannelErrors:
    """The errors of the sums of ``parts``: against the recording (``mse``), or, when the files' channels were
    filtered or averaged, against those (``mse_filtered``; ``mse`` is then ``None``: errors are reported against
    the recording, which the sums of filtered channels do not hold)."""
    if _filtered(parts):
        return ChannelErrors(None, n_samples, mse_filtered=mse)
    return ChannelErrors(mse, n_samples)


def _filtered(parts: Sequence[FileSums]) -> bool:
    """Whether the summed channels were low-pass filtered, period-averaged or decimated."""
    return any(part.metadata.get("margin", 0) or (part.metadata.get("periods_averaged") or 1) > 1
               or part.metadata.get("decimation", 1) > 1 for part in parts)


def streamed_channel_counts(streaming: dict[str, Any] | None) -> dict[str, dict] | None:
    """``result.json``'s ``channel_samples`` of a streamed fit (memory's
    :func:`~estimation.identification.prepared.channel_sample_counts`): for the training and the validation files
    whose sums left masked samples out (``channel_samples`` of :func:`streaming_record`'s files), the samples summed
    and each channel's valid ones; ``None`` when no channel's count differs, or when the sums hold filtered, averaged
    or decimated samples (not the samples as recorded)."""
    if not streaming:
        return None
    found = {}
    for role, key in (("train", "files"), ("validation", "validation_files")):
        files = streaming.get(key) or []
        if not any(entry.get("channel_samples") for entry in files):
            continue
        if any(entry.get("decimation", 1) > 1 or (entry.get("periods_averaged") or 1) > 1 for entry in files):
            continue
        samples = sum(int(entry["samples"]) for entry in files)
        names = next(entry["channel_samples"] for entry in files if entry.get("channel_samples"))
        found[role] = {"samples": samples, "channels": {
            name: sum(int(entry["channel_samples"][name] if entry.get("channel_samples") else entry["samples"])
                      for entry in files) for name in names}}
    return found or None


def _file_record(part: FileSums) -> dict[str, Any]:
    counts = part.sums.channel_samples  # each channel's valid samples where some were masked
    return {"path": part.path, "rows": part.rows, "samples": part.sums.n_samples,
            "channel_samples": None if counts is None else dict(zip(part.sums.channels, map(int, counts))),
            "decimation": part.metadata.get("decimation", 1), "margin": part.metadata.get("margin", 0),
            "periods_averaged": part.metadata.get("periods_averaged"),
            "resampled_from": part.metadata.get("resampled_from")}


def identify_files(
    model: IdentificationModel,
    paths: Sequence[str | Path],
    validate: Sequence[str | Path] = (),
    *,
    method: Literal["ols", "wls"] = "wls",
    chunk_size: int,
    cutoff_hz: float | None = None,
    frequency_hz: float | None = None,
    harmonics: int = 5,
    decimation: int = 1,
    held_torques: bool = False,
    executor: Any = None,
    covariance: StreamedCovariance = "hac",
) -> IdentificationResult:
    """Identify ``model`` from the training ``paths`` (one estimate) and validate on ``validate``.

    ``frequency_hz``: periodic records without ``dq``/``ddq`` take the Fourier path (periods averaged
    chunk by chunk, :mod:`estimation.streaming.periods`). Otherwise, without ``dq``/``ddq`` columns
    and without ``cutoff_hz``, the automatic cut-off of the first
    chunk of the first file (:func:`estimation.streaming.chunks.automatic_cutoff`) serves every file.
    ``executor``: see :func:`estimation.streaming.cluster.sum_files`. ``covariance``: ``"hac"`` (default) the
    batch-means standard deviations from a third pass over the training files (module docstring),
    ``"classical"`` the white-noise ones of the sums (no third pass).
    """
    return identify_files_candidates(
        model, paths, validate, methods=(method,), chunk_size=chunk_size, cutoff_hz=cutoff_hz,
        frequency_hz=frequency_hz, harmonics=harmonics, decimation=decimation, held_torques=held_torques,
        executor=executor, covariance=covariance).fits[method]


@dataclass(frozen=True)
class SummedFits:
    """The unconstrained fits of :func:`identify_files_candidates`, by method (the first asked for first), and the
    sums they were solved from: what the consistent refit (the training sums' Gram matrices,
    :func:`estimation.consistent.identification.consistent_fit_sums`) and the validation errors of other parameter
    vectors (the validation sums) need."""

    fits: dict[str, IdentificationResult]
    train: NormalEquations
    validation: NormalEquations | None
    files: tuple[FileSums, ...]
    validation_files: tuple[FileSums, ...]

    def train_errors(self, theta: NDArray[np.float64]) -> ChannelErrors:
        """The training errors of the base parameters ``theta``, from the sums."""
        return summed_errors(self.train.channel_mse(theta), int(self.train.n_samples), self.files)

    def validation_errors(self, theta: NDArray[np.float64]) -> ChannelErrors:
        """The validation errors of ``theta`` from the validation sums (against the recording only when the sums hold
        it: :func:`summed_errors`)."""
        if self.validation is None:
            raise ValueError("no validation files were summed")
        return summed_errors(self.validation.channel_mse(theta), int(self.validation.n_samples),
                             self.validation_files)


def identify_files_candidates(
    model: IdentificationModel,
    paths: Sequence[str | Path],
    validate: Sequence[str | Path] = (),
    *,
    methods: Sequence[Literal["ols", "wls"]] = ("wls", "ols"),
    chunk_size: int,
    cutoff_hz: float | None = None,
    frequency_hz: float | None = None,
    harmonics: int = 5,
    decimation: int = 1,
    held_torques: bool = False,
    executor: Any = None,
    covariance: StreamedCovariance = "hac",
    load: SubtractedLoad | None = None,
) -> SummedFits:
    """:func:`identify_files` of several weightings at once (``methods``, the first the one whose implausible values
    are warned of): the same sums solved with each, their batch-means standard deviations from the same third
    pass (one reading and one regressor a chunk for all), and the sums kept (:class:`SummedFits`). ``load``: a load
    of the description the logged torques lack (:mod:`estimation.identification.subtracted_load`), added back to
    every prepared chunk of every pass (:func:`estimation.streaming.chunks.loaded_chunk`: the robot's torques, as
    memory fits them; on the Fourier path at the fit's motion, :func:`estimation.streaming.periods.periodic_chunks`)."""
    if covariance not in ("hac", "classical"):
        raise ValueError(f"covariance must be 'hac' or 'classical', got {covariance!r}")
    methods = tuple(dict.fromkeys(methods))
    if not methods or not set(methods) <= {"ols", "wls"}:
        raise ValueError(f"methods must be among 'ols' and 'wls', got {methods!r}")
    paths = [str(path) for path in paths]
    if not paths:
        raise ValueError("no training data files")
    if frequency_hz is not None and cutoff_hz is not None:
        raise ValueError("give frequency_hz (Fourier fit of periodic data) or cutoff_hz (Butterworth filter), not both")
    if cutoff_hz is None and frequency_hz is None:
        try:
            cutoff_hz = None if _has_derivatives(paths[0], model, chunk_size) else automatic_cutoff(
                paths[0], model, chunk_size=chunk_size)
        except StopIteration:
            raise StreamingUnsupportedError(f"{paths[0]}: no samples") from None
    options = dict(chunk_size=chunk_size, cutoff_hz=cutoff_hz, decimation=decimation, held_torques=held_torques)
    if frequency_hz is not None:
        options.update(frequency_hz=frequency_hz, harmonics=harmonics)
    if load is not None:  # every pass below reads through these options (the sums, the covariance's)
        options["load"] = load
    # each file scanned once for this call's passes (the sums', the covariance's), in this process: the run's
    # FileScans handed to them (a worker scans its own file)
    scans = FileScans() if executor is None else None
    clock = time.perf_counter()
    with step(f"sums pass over {len(paths)} training file(s)"):
        train, files = sum_files(model, paths, executor=executor, scans=scans, **options)
    seconds = {"sums_pass": time.perf_counter() - clock}
    with step(f"sums pass over {len(validate)} validation file(s)"):
        validation, validation_files = (None, ()) if not validate else sum_files(model, validate, executor=executor,
                                                                                 scans=scans, **options)
    clock = time.perf_counter()
    estimates = {name: SummedLeastSquares(method=name, passive=passive_channels(model)).fit(train).estimate_
                 for name in methods}
    seconds["solve"] = time.perf_counter() - clock
    cov_method, batches, classical_std = "classical", dict.fromkeys(methods), dict.fromkeys(methods)
    if covariance == "hac":
        clock = time.perf_counter()
        with step(f"covariance pass over {len(paths)} training file(s)"):
            covariances = batch_means_covariance(
                model, files, train, options, [estimates[name].values for name in methods],
                [estimates[name].weights for name in methods], [estimates[name].cov for name in methods],
                executor=executor, scans=scans)
        seconds["covariance_pass"] = time.perf_counter() - clock
        cov_method = "batch_means"
        for name, (cov, batch) in zip(methods, covariances):
            estimate = estimates[name]
            std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
            with np.errstate(divide="ignore", invalid="ignore"):
                relative_std = np.where(estimate.values != 0, 100.0 * std / np.abs(estimate.values), np.inf)
            batches[name], classical_std[name] = batch, estimate.std
            estimates[name] = replace(estimate, cov=cov, std=std, relative_std=relative_std, cov_method="batch_means")
    trivial = None
    if validation is not None and validation.n_samples and not _filtered(validation_files):  # as recorded
        nominal = model.base.K @ model.nominal_parameters()
        trivial = {"zero_mse": dict(zip(model.channels, map(float, validation.power / validation.n_samples))),
                   "nominal_mse": validation.channel_mse(nominal)}
    sums = SummedFits({}, train, validation, tuple(files), tuple(validation_files))
    for name in methods:
        estimate = estimates[name]
        notes = implausible_estimates(model, estimate)  # type: ignore[arg-type]  (records() is all it reads)
        for note in notes if name == methods[0] else ():
            warnings.warn(note, ImplausibleEstimateWarning, stacklevel=2)
        streaming = streaming_record(
            chunk_size=int(chunk_size),
            cutoff_hz=None if all(part.metadata.get("cutoff_hz") is None for part in files) else cutoff_hz,
            frequency_hz=frequency_hz if any(part.metadata.get("differentiation") == "fourier" for part in files)
            else None, files=files, validation_files=tuple(validation_files), cov_method=cov_method,
            batch_length=batches[name], classical_std=None if classical_std[name] is None
            else dict(zip(estimate.names, map(float, classical_std[name]))),
            seconds={key: round(value, 3) for key, value in seconds.items()})
        sums.fits[name] = IdentificationResult(
            model, estimate, sums.train_errors(estimate.values),
            None if validation is None else sums.validation_errors(estimate.values), notes, path="streamed",
            not_computed=dict(STREAMED_NOT_COMPUTED), streaming=streaming, trivial=trivial)
    return sums


def _has_derivatives(path: str, model: IdentificationModel, chunk_size: int) -> bool:
    first = next(read_chunks(path, model, chunk_size=chunk_size))
    return first.dq is not None and first.ddq is not None


# ---------------------------------------------------------------- the batch-means standard deviations
#
# The batch-means standard deviations of the streamed identification: a third pass over its files.
#
# :func:`estimation.streaming.identification.identify_files` solves from the summed normal equations;
# their classical covariance assumes white residuals, which the filter path's derivative errors and
# any effect the model lacks make far too small. After the solve, one more pass over the training
# files (one task a file on the same executor, :func:`estimation.streaming.diagnosis_passes.map_files`)
# reads and prepares them again exactly as the sums did (the same chunks; on the Fourier path the
# same averaged period) and accumulates, at the final estimate ``θ̂``, the batch-means meat of the
# scores ``s_t = Σ_c w_c r_{c,t} Y_{c,t}`` (:class:`estimation.streaming.covariance.BatchScores`, batch
# lengths ``2^k`` in one pass, Andrews' rule). The covariance is the sandwich
# ``(YᵀWY)⁻¹ M (YᵀWY)⁻¹ · N/(N − p)`` of :func:`estimation.streaming.covariance.sandwich`, never below the
# classical one on the diagonal, as in memory. Memory: one chunk's regressor and ``17 p²`` floats.


def prepared_chunks(path: str, model: IdentificationModel, *, frequency_hz: float | None = None, harmonics: int = 5,
                    chunk_size: int = DEFAULT_CHUNK_SIZE, **options: Any) -> Iterator[Measurements]:
    """The prepared samples of one file, chunk by chunk, as :func:`estimation.streaming.cluster.sums_of_file` sums them
    (:func:`estimation.streaming.periods.plan_chunks`: on the Fourier path its averaged period, or its every sample
    with the fit's motion)."""
    yield from plan_chunks(path, model, frequency_hz=frequency_hz, harmonics=harmonics, chunk_size=chunk_size,
                           **options)


@single_threaded_blas()
def file_scores(path: str, model: IdentificationModel, options: dict[str, Any], theta: NDArray[np.float64],
                weights: NDArray[np.float64]) -> list[BatchScores]:
    """One file's :class:`BatchScores` of the base-parameter problem at each row of ``theta`` ``(k, r)`` (channel
    ``weights`` ``(k, m)``): one reading, one regressor a chunk for all of them."""
    layout = ColumnLayout.build(model, [])
    scores = [BatchScores.empty(model.n_base, model.n_channels) for _ in range(len(theta))]
    for chunk in prepared_chunks(path, model, **options):
        Y = model.evaluate_base(chunk.q, chunk.dq, chunk.ddq)
        for summed, values, weight in zip(scores, theta, weights):
            summed.add(*chunk_scores(model, layout, (), (), chunk, values, weight, Y=Y))
    return [summed.closed() for summed in scores]


def scores_task(payload: bytes, path: str, options: dict[str, Any], theta, weights, stamp=None):
    """Picklable: :func:`file_scores` on a worker (model rebuilt once a process), and its warnings."""
    return caught_warnings(file_scores, path, model_from_payload(payload), options, np.asarray(theta), np.asarray(weights))


def batch_means_covariance(model: IdentificationModel, files: Sequence[FileSums], train: NormalEquations,
                           options: dict[str, Any], theta: Sequence[NDArray[np.float64]],
                           weights: Sequence[NDArray[np.float64]], classical: Sequence[NDArray[np.float64]], *,
                           executor: Any = None, scans: FileScans | None = None
                           ) -> list[tuple[NDArray[np.float64], int]]:
    """The batch-means covariance of each estimate ``theta[i]`` (fitted with channel ``weights[i]``, its classical
    covariance ``classical[i]``) from one more pass over the training ``files`` (their sums ``train``, the reading
    ``options`` of :func:`estimation.streaming.cluster.sum_files`), and the batch length used, by estimate.
    ``scans``: the run's :class:`~estimation.streaming.chunks.FileScans` (in this process only), each file's scan
    taken from the sums pass.

    Raises
    ------
    IncompleteSumError
        A file gave other samples than when it was summed (changed meanwhile).
    WorkerLostError
        A worker lost (:func:`estimation.streaming.diagnosis_passes.map_files`).
    """
    paths = [part.path for part in files]
    if executor is None:  # in this process: the model as it is (rebuilding it from its payload costs seconds)
        def task(payload, path, options, theta, weights, stamp=None):
            return caught_warnings(file_scores, path, model, dict(options, scans=scans), theta, weights)
        payload = b""
    else:
        task, payload = scores_task, model_payload(model)
    theta, weights = np.atleast_2d(np.asarray(theta, dtype=float)), np.atleast_2d(np.asarray(weights, dtype=float))
    parts = map_files(executor, task, paths, lambda path: (payload, path, dict(options), theta, weights, file_stamp(path)))
    for part, scores in zip(files, parts):
        if any(estimate.n_samples != part.sums.n_samples for estimate in scores):
            raise IncompleteSumError(f"{part.path}: {scores[0].n_samples} samples scored, {part.sums.n_samples} summed "
                                     "(did the file change while it was read?)")
    return [sandwich([scores[index] for scores in parts], np.einsum("c,cij->ij", weight, train.gram), cov, weight)
            for index, (weight, cov) in enumerate(zip(weights, classical))]
