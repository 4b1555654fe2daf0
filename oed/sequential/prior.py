"""What the experiments already run say: their Fisher information under the identified model.

Each record is read and prepared as the model's identification did (its preprocessing, rows at rest,
delay: :class:`estimation.identification.identified_model.IdentifiedModel`), and its information is
``Σ_k J_kᵀ J_k`` over its samples with the model's noise-weighted Jacobian
(:mod:`oed.sequential.jacobian`). Its inverse is the covariance the experiments give the parameters
under white noise of the model's channel variances (the classical, not the batch-means, covariance).
The samples' spacing makes the rate at which a new experiment of the same set-up adds samples.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from estimation.identification.identified_model import IdentifiedModel
from estimation.preprocessing.delay import delayed
from oed.sequential.jacobian import ModelJacobian, SequentialDesignError

__all__ = ["PriorInformation", "prior_information", "read_records"]


@dataclass(frozen=True)
class PriorInformation:
    """The information of the experiments run so far.

    Attributes
    ----------
    information
        ``(p, p)`` Fisher information of the parameters (:attr:`ModelJacobian.names` order).
    n_samples
        Samples the records hold (after preparation).
    sample_time_s
        Median spacing of their samples, s: a new experiment adds one sample per ``sample_time_s``.
    """

    information: NDArray[np.float64] = field(repr=False)
    n_samples: int
    sample_time_s: float

    @property
    def duration_s(self) -> float:
        """The experiments' length, ``n_samples · sample_time_s``."""
        return self.n_samples * self.sample_time_s

    def samples_in(self, duration_s: float) -> float:
        """Samples a new experiment of ``duration_s`` seconds adds."""
        return duration_s / self.sample_time_s

    def covariance(self) -> NDArray[np.float64]:
        """``information⁻¹``; :class:`SequentialDesignError` when the records leave a parameter undetermined."""
        return posterior_covariance(self.information)


def posterior_covariance(information: NDArray[np.float64]) -> NDArray[np.float64]:
    """The inverse of a positive definite information matrix (scaled to unit diagonal for accuracy)."""
    diagonal = np.diag(information)
    if np.any(~np.isfinite(diagonal)) or np.any(diagonal <= 0):
        raise SequentialDesignError("the records carry no information on some parameter (a zero column of the "
                                    "Jacobian): they do not match the model")
    scale = 1.0 / np.sqrt(diagonal)
    scaled = information * scale[:, None] * scale[None, :]
    try:
        factor = np.linalg.cholesky((scaled + scaled.T) / 2)
    except np.linalg.LinAlgError:
        raise SequentialDesignError("the records leave the model's parameters undetermined (singular information): "
                                    "they are not the records the model was identified on") from None
    inverse = np.linalg.inv(factor)
    return (inverse.T @ inverse) * scale[:, None] * scale[None, :]


def read_records(model: IdentifiedModel, paths: Sequence[str | Path]) -> Measurements:
    """The records in ``paths`` read, prepared as the model's identification prepared its data, and moved by its delay.

    Raises
    ------
    SequentialDesignError
        When a record's joints do not match the model's robot.
    """
    if not paths:
        raise SequentialDesignError("give the records of the experiments already run (--data)")
    try:
        segments = model.read(paths)
    except (KeyError, ValueError) as error:
        raise SequentialDesignError(f"the records do not match the model ({model.robot.name}, joints "
                                    f"{', '.join(model.file.joint_names)}): {error}") from None
    prepared = model.prepare(segments)
    return prepared if model.delay is None else delayed(prepared, model.delay)


def prior_information(jacobian: ModelJacobian, records: Measurements) -> PriorInformation:
    """The :class:`PriorInformation` of prepared records (``q, dq, ddq`` present)."""
    if records.dq is None or records.ddq is None:
        raise SequentialDesignError("the records lack dq/ddq: prepare them first (read_records)")
    if records.q.shape[1] != jacobian.function.size1_in(0):
        raise SequentialDesignError(f"the records have {records.q.shape[1]} joints, the model "
                                    f"{jacobian.function.size1_in(0)}")
    information = jacobian.information(records.q, records.dq, records.ddq)
    steps = np.diff(records.t)
    steps = steps[steps > 0]
    if steps.size == 0:
        raise SequentialDesignError("the records hold fewer than two samples")
    return PriorInformation(information, int(records.q.shape[0]), float(np.median(steps)))
