"""The batch-means standard deviations of the streamed identification: a third pass over its files.

:func:`estimation.streaming.identification.identify_files` solves from the summed normal equations;
their classical covariance assumes white residuals, which the filter path's derivative errors and
any effect the model lacks make far too small. After the solve, one more pass over the training
files (one task a file on the same executor, :func:`estimation.streaming.diagnosis_passes.map_files`)
reads and prepares them again exactly as the sums did (the same chunks; on the Fourier path the
same averaged period) and accumulates, at the final estimate ``θ̂``, the batch-means meat of the
scores ``s_t = Σ_c w_c r_{c,t} Y_{c,t}`` (:class:`estimation.streaming.covariance.BatchScores`, batch
lengths ``2^k`` in one pass, Andrews' rule). The covariance is the sandwich
``(YᵀWY)⁻¹ M (YᵀWY)⁻¹ · N/(N − p)`` of :func:`estimation.streaming.covariance.sandwich`, never below the
classical one on the diagonal, as in memory. Memory: one chunk's regressor and ``17 p²`` floats.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dynamics.models import IdentificationModel
from dynamics.runtime.threads import single_threaded_blas
from estimation.streaming.cluster import IncompleteSumError, caught_warnings, file_stamp, model_from_payload, model_payload
from estimation.streaming.diagnosis_sums import ColumnLayout
from dynamics.measurements import Measurements
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE, NormalEquations
from estimation.streaming.diagnosis_passes import map_files
from estimation.streaming.chunks import FileSums, preprocessed_chunks, read_chunks
from estimation.streaming.periods import periodic_prepared
from estimation.streaming.covariance import BatchScores, chunk_scores, sandwich

__all__ = ["batch_means_covariance", "file_scores", "prepared_chunks", "scores_task"]


def prepared_chunks(path: str, model: IdentificationModel, *, frequency_hz: float | None = None, harmonics: int = 5,
                    chunk_size: int = DEFAULT_CHUNK_SIZE, **options: Any) -> Iterator[Measurements]:
    """The prepared samples of one file, chunk by chunk, as :func:`estimation.streaming.cluster.sums_of_file` sums them."""
    if frequency_hz is not None:
        first = next(read_chunks(path, model, chunk_size=chunk_size))
        if first.dq is None or first.ddq is None:
            prepared = periodic_prepared(path, model, frequency_hz=frequency_hz, harmonics=harmonics,
                                         chunk_size=chunk_size, **{key: options[key] for key in
                                                                   ("decimation", "held_torques") if key in options})[0]
            for start in range(0, prepared.n_samples, chunk_size):
                yield prepared.select(slice(start, start + chunk_size))
            return
    yield from preprocessed_chunks(path, model, chunk_size=chunk_size, **options)


@single_threaded_blas()
def file_scores(path: str, model: IdentificationModel, options: dict[str, Any], theta: NDArray[np.float64],
                weights: NDArray[np.float64]) -> BatchScores:
    """One file's :class:`BatchScores` of the base-parameter problem at ``theta`` (channel ``weights``)."""
    layout = ColumnLayout.build(model, [])
    scores = BatchScores.empty(model.n_base, model.n_channels)
    for chunk in prepared_chunks(path, model, **options):
        scores.add(*chunk_scores(model, layout, (), (), chunk, theta, weights))
    return scores.closed()


def scores_task(payload: bytes, path: str, options: dict[str, Any], theta, weights, stamp=None):
    """Picklable: :func:`file_scores` on a worker (model rebuilt once a process), and its warnings."""
    return caught_warnings(file_scores, path, model_from_payload(payload), options, np.asarray(theta), np.asarray(weights))


def batch_means_covariance(model: IdentificationModel, files: Sequence[FileSums], train: NormalEquations,
                           options: dict[str, Any], theta: NDArray[np.float64], weights: NDArray[np.float64],
                           classical: NDArray[np.float64], *, executor: Any = None
                           ) -> tuple[NDArray[np.float64], int]:
    """The batch-means covariance of ``theta`` (fitted with channel ``weights``) from one more pass over
    the training ``files`` (their sums ``train``, the reading ``options`` of
    :func:`estimation.streaming.cluster.sum_files`), and the batch length used.

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
            return caught_warnings(file_scores, path, model, options, theta, weights)
        payload = b""
    else:
        task, payload = scores_task, model_payload(model)
    parts = map_files(executor, task, paths, lambda path: (payload, path, dict(options), theta, weights, file_stamp(path)))
    for part, scores in zip(files, parts):
        if scores.n_samples != part.sums.n_samples:
            raise IncompleteSumError(f"{part.path}: {scores.n_samples} samples scored, {part.sums.n_samples} summed "
                                     "(did the file change while it was read?)")
    normal = np.einsum("c,cij->ij", np.asarray(weights, dtype=float), train.gram)
    return sandwich(parts, normal, classical, np.asarray(weights, dtype=float))
