"""The payload design's criterion: the worst relative standard deviation of the mass and the centre of mass.

Of a payload's ten parameters ``π = (m, h, I_O)`` a controller needs the mass and the centre of mass ``c = h/m``
first; the inertia is nuisance here. Near a guess ``(m₀, c₀)`` the centre of mass moves as ``δc = (δh − c₀ δm)/m₀``,
so the quantities to know are the linear combinations ``u = T π``,

    u_0 = m / m₀,      u_i = (h_i − c₀_i m) / (m₀ ℓ)   (i = 1..3),

relative to the mass and to a length ``ℓ`` (a tool's size). With ``M`` the information of ``π`` (noise-weighted),
``var(u_k) = (T M⁻¹ Tᵀ)_kk`` (the inertia's parameters unknown too: the marginal variances), and the criterion is
a smooth maximum of their logarithms, the log-sum-exp at sharpness ``κ``,

    J = (1/κ) log Σ_k var(u_k)^κ ,       max_k log var(u_k) ≤ J ≤ max_k log var(u_k) + (log 4)/κ,

the worst relative variance of the four (as :class:`oed.sequential.criteria.WorstRelativeVariance`, for linear
combinations). D-optimality over all ten would spend information on the inertia the controller needs least.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import casadi
import numpy as np
from numpy.typing import ArrayLike, NDArray

from oed.criteria import Criterion

__all__ = ["DEFAULT_LENGTH", "DEFAULT_MASS", "SHARPNESS", "MassAndCentre"]

#: the mass (kg) and length (m) the design assumes without a guess of the payload
DEFAULT_MASS = 1.0
DEFAULT_LENGTH = 0.1
#: ``κ``: the smooth maximum exceeds the worst log variance by at most log(4)/κ (17 % in variance, 9 % in std)
SHARPNESS = 8.0


@dataclass(frozen=True)
class MassAndCentre(Criterion):
    """``(1/κ) log Σ_k var(u_k)^κ`` over the mass and centre-of-mass combinations ``u = T π`` (module docstring).

    Parameters
    ----------
    mass, com, length
        The guess ``m₀`` (kg), ``c₀`` (m, link frame) and the length ``ℓ`` (m) the centre of mass is relative to.
    sharpness
        ``κ > 0``.
    """

    mass: float = DEFAULT_MASS
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    length: float = DEFAULT_LENGTH
    sharpness: float = SHARPNESS
    name: ClassVar[str] = "payload-worst-relative"
    smooth: ClassVar[bool] = True

    def __post_init__(self) -> None:
        for name in ("mass", "length", "sharpness"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value}")
        com = tuple(float(value) for value in np.asarray(self.com, dtype=float).reshape(-1))
        if len(com) != 3 or not all(np.isfinite(com)):
            raise ValueError(f"com must be three finite numbers (m), got {self.com!r}")
        object.__setattr__(self, "com", com)

    @property
    def combinations(self) -> NDArray[np.float64]:
        """``T`` (4 x 10): the relative mass and centre-of-mass combinations of ``π``."""
        T = np.zeros((4, 10))
        T[0, 0] = 1.0 / self.mass
        for i in range(3):
            T[1 + i, 1 + i] = 1.0 / (self.mass * self.length)
            T[1 + i, 0] = -self.com[i] / (self.mass * self.length)
        return T

    def relative_std(self, M: ArrayLike) -> NDArray[np.float64]:
        """Standard deviations of ``u`` (relative mass, centre of mass in units of ``ℓ``) for the information ``M``."""
        M = np.asarray(M, dtype=float)
        T = self.combinations
        try:
            variances = np.sum(T.T * np.linalg.solve((M + M.T) / 2, T.T), axis=0)
        except np.linalg.LinAlgError:
            return np.full(4, np.inf)
        return np.sqrt(np.where(variances > 0, variances, np.inf))

    def expression(self, M):
        T = casadi.DM(self.combinations)
        variances = casadi.sum1(T.T * casadi.solve(M, T.T)).T
        logs = casadi.log(variances)
        top = casadi.mmax(logs)  # a shift that leaves the value and its derivative alone
        return top + casadi.log(casadi.sum1(casadi.exp(self.sharpness * (logs - top)))) / self.sharpness

    def value(self, M: ArrayLike) -> float:
        std = self.relative_std(M)
        if not np.all(np.isfinite(std)):
            return float("inf")
        logs = 2 * np.log(std)
        top = float(np.max(logs))
        return top + float(np.log(np.sum(np.exp(self.sharpness * (logs - top))))) / self.sharpness
