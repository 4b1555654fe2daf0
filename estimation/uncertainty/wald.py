"""The Wald test of coefficients against zero from a covariance that holds for residuals correlated in time.

``W = θᵀ C⁻¹ θ ~ χ²_k`` under ``θ = 0`` (``C`` a HAC or batch-means covariance, :mod:`estimation.uncertainty.covariance`,
:mod:`estimation.uncertainty.batch_means`): the statistic the diagnosis adopts and reports effects with
(:mod:`estimation.diagnosis.rules.robust_test`) and ``oed predict``'s check of a changed load or mount
(:mod:`estimation.identification.record_changes`) says a change with.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.stats
from numpy.typing import NDArray

__all__ = ["WaldTest", "wald_test"]


@dataclass(frozen=True)
class WaldTest:
    """``W = θ_bᵀ C_bb⁻¹ θ_b`` of ``dof`` coefficients and its χ² p-value (module docstring)."""

    statistic: float
    p_value: float
    dof: int

    @property
    def f_statistic(self) -> float:
        """``W / k``: the F statistic of the test made robust."""
        return self.statistic / max(self.dof, 1)


def wald_test(theta: NDArray[np.float64], cov: NDArray[np.float64]) -> WaldTest:
    """The Wald test of ``θ = 0`` with covariance ``cov`` (a pseudo-inverse: a direction without
    variance carries no evidence)."""
    theta = np.atleast_1d(np.asarray(theta, dtype=float))
    cov = np.atleast_2d(np.asarray(cov, dtype=float))
    if theta.size == 0:
        return WaldTest(0.0, 1.0, 0)
    if not (np.all(np.isfinite(theta)) and np.all(np.isfinite(cov))):
        return WaldTest(float("nan"), 1.0, theta.size)
    scale = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    scale = np.where(scale > 0, scale, 1.0)
    statistic = float(max((theta / scale) @ np.linalg.pinv(cov / np.outer(scale, scale), hermitian=True)
                          @ (theta / scale), 0.0))
    return WaldTest(statistic, float(scipy.stats.chi2.sf(statistic, theta.size)), int(theta.size))
