"""D- and Ds-optimality on the information of a sequence of experiments.

With ``M`` the information of every parameter (prior plus the new experiment's), D-optimality
minimises ``−log det M``: the volume of the joint confidence ellipsoid. When a user cares about a group
``f`` of the parameters only (one effect's coefficients and shape, say) and the others ``o`` are nuisance,
Ds-optimality (Atkinson, Donev and Tobias, *Optimum Experimental Designs, with SAS*, Oxford 2007,
section 10.3) minimises the log-determinant of the focus group's marginal covariance,
``log det (M⁻¹)_ff = −log det (M_ff − M_fo M_oo⁻¹ M_of) = −(log det M − log det M_oo)``: the Schur complement
by two Cholesky factors, with exact derivatives.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import casadi
import numpy as np
from numpy.typing import ArrayLike

from oed.criteria import Criterion, LogDet
from oed.sequential.jacobian import ModelJacobian, SequentialDesignError

__all__ = ["FocusedLogDet", "focus_names", "posterior_criterion", "scaled", "symbolic_scaled"]


@dataclass(frozen=True)
class FocusedLogDet(Criterion):
    """``−log det(M_ff − M_fo M_oo⁻¹ M_of)`` for the focus parameters ``f`` of a ``p x p`` information ``M``
    (Ds-optimality, module docstring).

    Parameters
    ----------
    focus
        Positions of the focus parameters (the others are the nuisance ``o``).
    n_parameters
        ``p``.
    weight
        ``w ∈ [0, 1]``: minimise ``Ds + w D`` (``D = −log det M``), a compromise that keeps some weight on the
        whole model when the focus group alone would let the other parameters' information collapse.
    """

    focus: tuple[int, ...]
    n_parameters: int
    weight: float = 0.0
    name: ClassVar[str] = "ds-logdet"

    def __post_init__(self) -> None:
        focus = tuple(int(index) for index in self.focus)
        if not focus or len(set(focus)) != len(focus) or not all(0 <= index < self.n_parameters for index in focus):
            raise ValueError(f"focus must be distinct positions among {self.n_parameters} parameters, got {self.focus!r}")
        object.__setattr__(self, "focus", tuple(sorted(focus)))
        if not (np.isfinite(self.weight) and 0 <= self.weight <= 1):
            raise ValueError(f"weight must be in [0, 1], got {self.weight}")

    @property
    def others(self) -> list[int]:
        return [index for index in range(self.n_parameters) if index not in set(self.focus)]

    def expression(self, M):
        full = LogDet().expression(M)
        others = self.others
        if not others:
            return full
        return (1 + self.weight) * full - LogDet().expression(M[others, others])

    def value(self, M: ArrayLike) -> float:
        M = np.asarray(M, dtype=float)
        others = self.others
        full = LogDet().value(M)
        return full if not others else (1 + self.weight) * full - LogDet().value(M[np.ix_(others, others)])


def focus_names(jacobian: ModelJacobian, focus: str | Sequence[str] | None) -> tuple[str, ...]:
    """The parameters a ``--focus`` names: parameter names (``fs2``, ``vs2``) or effects, by name
    (``stribeck``) or spec (``stribeck:velocity@2``), comma-separated; ``None``: every parameter.

    Raises
    ------
    SequentialDesignError
        A name that is neither a parameter nor an effect of the model, or an effect with no parameter of
        its own (its coefficients merged into base parameters).
    """
    if focus is None:
        return jacobian.names
    items = [item.strip() for item in (focus.split(",") if isinstance(focus, str) else focus) if item.strip()]
    if not items:
        raise SequentialDesignError("--focus names no parameter")
    chosen: set[str] = set()
    for item in items:
        if item in jacobian.names:
            chosen.add(item)
            continue
        matches = [names for name, spec, names in jacobian.effects if item in (name, spec)]
        if not matches:
            effects = ", ".join(spec for _, spec, _ in jacobian.effects) or "none"
            raise SequentialDesignError(f"--focus {item!r} is neither a parameter of the model nor one of its effects "
                                        f"({effects}); its parameters are {', '.join(jacobian.names)}")
        if not any(matches):
            raise SequentialDesignError(f"--focus {item!r}: the effect has no base parameter of its own in this model")
        for names in matches:
            chosen.update(names)
    return tuple(name for name in jacobian.names if name in chosen)


def posterior_criterion(jacobian: ModelJacobian, focus: Sequence[str]) -> Criterion:
    """``LogDet`` when ``focus`` is every parameter, else the :class:`FocusedLogDet` of those parameters."""
    if set(focus) == set(jacobian.names):
        return LogDet()
    return FocusedLogDet(jacobian.indices(focus), jacobian.n_parameters)


def scaled(M: ArrayLike, scale: ArrayLike) -> np.ndarray:
    """``D M D`` with ``D = diag(scale)``."""
    scale = np.asarray(scale, dtype=float)
    return np.asarray(M, dtype=float) * scale[:, None] * scale[None, :]


def symbolic_scaled(M: casadi.MX, scale: ArrayLike) -> casadi.MX:
    """``D M D`` of a symbolic matrix."""
    D = casadi.diag(casadi.DM(np.asarray(scale, dtype=float)))
    return casadi.mtimes(casadi.mtimes(D, M), D)
