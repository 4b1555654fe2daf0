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

**The robot model's share.** The payload is fitted against the robot model's prediction, whose parameters ``θ_b``
are uncertain (covariance ``Σ_θ``); their error moves the payload estimate by ``A⁻¹ B δθ_b`` (``A = n M_kk`` and
``B = n M_kb`` the record's information of the payload's and the robot's columns together, ``n`` samples,
:mod:`estimation.payload.fit`). Without ``robot_cov`` (the default of ``oed design --payload``, issue 37's target)
the criterion counts the record's noise alone, ``(1/n) M⁻¹``, the robot model given. Given ``Σ_θ`` (``robot_cov``)
it acts on the information ``M`` of the stacked columns ``[Y_k | Y_b]`` (per sample) and counts both parts,

    cov(π) = (1/n) M_kk⁻¹ + M_kk⁻¹ M_kb Σ_θ M_bk M_kk⁻¹ ;

:meth:`MassAndCentre.relative_variances` gives the two apart either way (with ``robot_cov``). A design for the
record's noise alone drives the motion where the robot model is least known (measured on the PUMA: the robot's share
of the mass's standard deviation about four times that of random excitations).
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


@dataclass(frozen=True, eq=False)
class MassAndCentre(Criterion):
    """``(1/κ) log Σ_k var(u_k)^κ`` over the mass and centre-of-mass combinations ``u = T π`` (module docstring).

    Parameters
    ----------
    mass, com, length
        The guess ``m₀`` (kg), ``c₀`` (m, link frame) and the length ``ℓ`` (m) the centre of mass is relative to.
    sharpness
        ``κ > 0``.
    robot_cov
        ``Σ_θ`` (``r x r``) of the robot model's parameters, or ``None``: the record's noise alone, ``M`` then the
        information of the payload's ten parameters.
    samples
        ``n``: the samples of the record, ``M`` being per sample (default 1: ``M`` is the record's information).
    """

    mass: float = DEFAULT_MASS
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    length: float = DEFAULT_LENGTH
    sharpness: float = SHARPNESS
    robot_cov: NDArray[np.float64] | None = None
    samples: float = 1.0
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
        if not (np.isfinite(self.samples) and self.samples > 0):
            raise ValueError(f"samples must be positive, got {self.samples}")
        if self.robot_cov is not None:
            cov = np.asarray(self.robot_cov, dtype=float)
            if cov.ndim != 2 or cov.shape[0] != cov.shape[1] or not np.all(np.isfinite(cov)):
                raise ValueError(f"robot_cov must be a finite square matrix, got shape {cov.shape}")
            object.__setattr__(self, "robot_cov", (cov + cov.T) / 2)

    @property
    def size(self) -> int:
        """The size of the information ``M`` the criterion takes: 10, or 10 + r with ``robot_cov``."""
        return 10 + (0 if self.robot_cov is None else self.robot_cov.shape[0])

    @property
    def combinations(self) -> NDArray[np.float64]:
        """``T`` (4 x 10): the relative mass and centre-of-mass combinations of ``π``."""
        T = np.zeros((4, 10))
        T[0, 0] = 1.0 / self.mass
        for i in range(3):
            T[1 + i, 1 + i] = 1.0 / (self.mass * self.length)
            T[1 + i, 0] = -self.com[i] / (self.mass * self.length)
        return T

    def relative_variances(self, M: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Variances of ``u`` (relative mass, centre of mass in units of ``ℓ``) for the information ``M``: the record's
        noise part and the robot model's (zero without ``robot_cov``)."""
        M = np.asarray(M, dtype=float)
        M = (M + M.T) / 2
        T = self.combinations
        try:
            X = np.linalg.solve(M[:10, :10], T.T)
        except np.linalg.LinAlgError:
            return np.full(4, np.inf), np.zeros(4)
        noise = np.sum(T.T * X, axis=0) / self.samples
        if self.robot_cov is None:
            return noise, np.zeros(4)
        Z = M[10:, :10] @ X
        return noise, np.sum(Z * (self.robot_cov @ Z), axis=0)

    def relative_std(self, M: ArrayLike) -> NDArray[np.float64]:
        """Standard deviations of ``u``, both parts together."""
        noise, robot = self.relative_variances(M)
        total = noise + robot
        return np.sqrt(np.where(noise > 0, total, np.inf))

    def variance_expressions(self, M) -> tuple[casadi.MX, casadi.MX | None]:
        """:meth:`relative_variances` as CasADi expressions of ``M`` (``(10 + r) x 10`` suffices: the first ten
        columns): the record's noise part and the robot model's (``None`` without ``robot_cov``), each ``4 x 1``."""
        T = casadi.DM(self.combinations)
        X = casadi.solve(M[:10, :10], T.T)
        noise = casadi.sum1(T.T * X).T / self.samples
        if self.robot_cov is None:
            return noise, None
        Z = casadi.mtimes(M[10:, :10], X)
        return noise, casadi.sum1(Z * casadi.mtimes(casadi.DM(self.robot_cov), Z)).T

    def expression(self, M):
        noise, robot = self.variance_expressions(M)
        variances = noise if robot is None else noise + robot
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
