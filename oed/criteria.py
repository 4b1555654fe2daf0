"""Design criteria on the information matrix ``M = Y_bᵀ Y_b`` of the stacked base regressor.

The PUMA paper (section IV.A) minimises ``−log det(Y_bᵀ Y_b)`` (D-optimality). The condition
number of ``Y_b`` and the smallest eigenvalue of ``M`` (E-optimality) are the usual alternatives.
Each criterion is a small frozen object with

- :meth:`expression` — the CasADi expression to *minimise*, from a symbolic ``M`` (SX or MX);
- :meth:`value` — the same number from a numeric ``M`` (numpy), for reports;
- :meth:`from_regressor` — both from a stacked base regressor ``Y_b`` instead of ``M``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import ClassVar, Literal

import casadi
import numpy as np
from numpy.typing import ArrayLike, NDArray

CriterionName = Literal["logdet", "cond", "mineig"]


def information_matrix(Y_base: ArrayLike) -> NDArray[np.float64]:
    """``Σ_k Y_kᵀ Y_k`` from a stack ``(N, rows, r)`` or ``(N·rows, r)`` of base regressors."""
    Y = np.asarray(Y_base, dtype=float)
    Y = Y.reshape(-1, Y.shape[-1])
    return Y.T @ Y


def _symmetric(M: ArrayLike) -> NDArray[np.float64]:
    M = np.asarray(M, dtype=float)
    if M.ndim != 2 or M.shape[0] != M.shape[1]:
        raise ValueError(f"information matrix must be square, got shape {M.shape}")
    return (M + M.T) / 2


class _Criterion:
    name: ClassVar[str]
    #: differentiable wherever it is finite (quasi-Newton models hold); the eigenvalue criteria have
    #: kinks where the extreme eigenvalues cross
    smooth: ClassVar[bool] = False

    def expression(self, M: casadi.SX | casadi.MX) -> casadi.SX | casadi.MX:  # pragma: no cover - interface
        raise NotImplementedError

    def value(self, M: ArrayLike) -> float:  # pragma: no cover - interface
        raise NotImplementedError

    def from_regressor(self, Y_base: casadi.SX | casadi.MX | ArrayLike):
        """The criterion of a stacked base regressor (symbolic ``(N·rows, r)`` or numeric)."""
        if isinstance(Y_base, (casadi.SX, casadi.MX)):
            return self.expression(casadi.mtimes(Y_base.T, Y_base))
        return self.value(information_matrix(Y_base))

    def function(self, r: int) -> casadi.Function:
        """``criterion(M) -> J`` as a named CasADi function of an ``r x r`` information matrix."""
        return _criterion_function(self, r)


@functools.lru_cache(maxsize=32)
def _criterion_function(criterion: _Criterion, r: int) -> casadi.Function:
    M = casadi.SX.sym("M", r, r)
    return casadi.Function(f"{criterion.name}_criterion", [M], [criterion.expression(M)], ["M"], ["J"])


@dataclass(frozen=True)
class LogDet(_Criterion):
    """``−log det(M + λ I)`` via the Cholesky factor, ``−2 Σ log L_ii`` (PUMA paper, section IV.A).

    Parameters
    ----------
    regularization
        ``λ ≥ 0`` added to the diagonal, keeping the criterion finite near singular designs.
    """

    regularization: float = 0.0
    name: ClassVar[str] = "logdet"
    smooth: ClassVar[bool] = True

    def __post_init__(self) -> None:
        if not (np.isfinite(self.regularization) and self.regularization >= 0):
            raise ValueError(f"regularization must be a non-negative number, got {self.regularization}")

    def expression(self, M):
        if self.regularization:
            M = M + self.regularization * casadi.DM.eye(M.shape[0])
        if isinstance(M, casadi.MX):
            return _criterion_function(self, M.shape[0])(M)
        upper = casadi.chol(M)  # M = Lᵀ L with L upper triangular
        return -2 * casadi.sum1(casadi.log(casadi.diag(upper)))

    def value(self, M) -> float:
        M = _symmetric(M) + self.regularization * np.eye(np.shape(M)[0])
        sign, logdet = np.linalg.slogdet(M)
        return float(-logdet) if sign > 0 else float("inf")


@dataclass(frozen=True)
class ConditionNumber(_Criterion):
    """Condition number of ``Y_b``: ``sqrt(λ_max(M) / λ_min(M))``."""

    name: ClassVar[str] = "cond"

    def expression(self, M):
        eigenvalues = symmetric_eigenvalues(M.shape[0])(M)
        return casadi.sqrt(eigenvalues[-1] / eigenvalues[0])

    def value(self, M) -> float:
        eigenvalues = np.linalg.eigvalsh(_symmetric(M))
        return float(np.sqrt(eigenvalues[-1] / eigenvalues[0])) if eigenvalues[0] > 0 else float("inf")


@dataclass(frozen=True)
class MinEigenvalue(_Criterion):
    """``−λ_min(M)`` (E-optimality: maximise the smallest eigenvalue of the information matrix)."""

    name: ClassVar[str] = "mineig"

    def expression(self, M):
        return -symmetric_eigenvalues(M.shape[0])(M)[0]

    def value(self, M) -> float:
        return float(-np.linalg.eigvalsh(_symmetric(M))[0])


CRITERIA: dict[str, type[_Criterion]] = {"logdet": LogDet, "cond": ConditionNumber, "mineig": MinEigenvalue}
Criterion = _Criterion


def criterion_from_name(name: str | _Criterion) -> _Criterion:
    """``"logdet"``, ``"cond"`` or ``"mineig"`` (or a criterion object, returned as is)."""
    if isinstance(name, _Criterion):
        return name
    if not isinstance(name, str):
        raise TypeError(f"criterion must be a name or a criterion object, got {type(name).__name__}")
    key = name.strip().lower().replace("-", "").replace("_", "")
    aliases = {"logdet": "logdet", "dopt": "logdet", "cond": "cond", "condition": "cond", "conditionnumber": "cond",
               "mineig": "mineig", "mineigenvalue": "mineig", "eopt": "mineig"}
    if key not in aliases:
        raise ValueError(f"unknown criterion {name!r}; expected one of {sorted(CRITERIA)}")
    return CRITERIA[aliases[key]]()


class _EigenvaluesCallback(casadi.Callback):
    """Ascending eigenvalues of a symmetric ``r x r`` matrix, with the reverse derivative
    ``adj_M = Σ_i adj_λ_i v_i v_iᵀ`` (exact for simple eigenvalues)."""

    def __init__(self, r: int) -> None:
        casadi.Callback.__init__(self)
        self.r = r
        self._reverse = None
        self.construct(f"symmetric_eigenvalues_{r}", {})

    def get_n_in(self):
        return 1

    def get_n_out(self):
        return 1

    def get_sparsity_in(self, i):
        return casadi.Sparsity.dense(self.r, self.r)

    def get_sparsity_out(self, i):
        return casadi.Sparsity.dense(self.r, 1)

    def eval(self, arg):
        return [np.linalg.eigvalsh(_symmetric(np.asarray(arg[0])))]

    def has_reverse(self, nadj):
        return nadj == 1

    def get_reverse(self, nadj, name, inames, onames, opts):
        if self._reverse is None:
            self._reverse = _EigenvaluesReverse(self.r, name, opts)
        return self._reverse


class _EigenvaluesReverse(casadi.Callback):
    def __init__(self, r: int, name: str, opts: dict) -> None:
        casadi.Callback.__init__(self)
        self.r = r
        self.construct(name, {})

    def get_n_in(self):
        return 3  # M, λ (nominal output), adj_λ

    def get_n_out(self):
        return 1

    def get_sparsity_in(self, i):
        return casadi.Sparsity.dense(self.r, self.r) if i == 0 else casadi.Sparsity.dense(self.r, 1)

    def get_sparsity_out(self, i):
        return casadi.Sparsity.dense(self.r, self.r)

    def eval(self, arg):
        _, vectors = np.linalg.eigh(_symmetric(np.asarray(arg[0])))
        seed = np.asarray(arg[2]).reshape(-1)
        return [(vectors * seed) @ vectors.T]


@functools.lru_cache(maxsize=16)
def symmetric_eigenvalues(r: int) -> casadi.Function:
    """A cached CasADi function ``M (r x r) -> λ (r, ascending)`` with an exact reverse derivative."""
    return _EigenvaluesCallback(r)
