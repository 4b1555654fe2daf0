"""The filter cut-off of a streamed record, chosen by held-out evidence on a window of it.

The streamed identification and diagnosis derive ``dq, ddq`` with one zero-phase Butterworth filter for every chunk
and file. Its cut-off was the bandwidth rule (:func:`estimation.streaming.chunks.automatic_cutoff`: five times the
first chunk's motion bandwidth); here it is chosen as the in-memory path chooses its derivatives
(:func:`estimation.identification.preprocessing_choice.choose_by_evidence`, the filter candidates only: the
streamed path filters), on the first :data:`~estimation.identification.preprocessing_choice.SCORED_SAMPLES` rows
of the first training file, which is also the window the in-memory path scores a long record on. Memory stays
bounded by that window.
"""

from __future__ import annotations

import warnings
from pathlib import Path

from dynamics.models import IdentificationModel
from estimation.identification.preprocessing_choice import SCORED_SAMPLES, choose_by_evidence
from estimation.preprocessing.plan import Preprocessing, PreprocessingWarning
from estimation.streaming.chunks import read_chunks

__all__ = ["choose_streamed_cutoff"]


def choose_streamed_cutoff(path: str | Path, model: IdentificationModel, *, decimation: int = 1,
                           held_torques: bool = False) -> Preprocessing | None:
    """The Butterworth plan chosen on the first rows of ``path`` (module docstring), with its evidence; ``None``
    when the file holds measured ``dq, ddq`` (nothing to choose)."""
    first = next(read_chunks(path, model, chunk_size=SCORED_SAMPLES))
    if first.dq is not None and first.ddq is not None:
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PreprocessingWarning)
        return choose_by_evidence(model, [first], decimation=decimation, held_torques=held_torques,
                                  families=("butterworth",)).chosen
