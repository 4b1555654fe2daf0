"""Minimal (base) parameters by pivoted QR of the regressor over random states.

Stack the regressor ``Y`` over random states (columns scaled to unit norm), factor
``Y P = Q R`` with column pivoting, and keep the ``r`` leading columns (``|R_kk|`` above a
relative tolerance): they are independent, the others are combinations of them,
``Y_dep = Y_ind β`` with ``β = R_11⁻¹ R_12``. Then

.. math::  Y θ = Y_{base} θ_{base}, \\qquad θ_{base} = θ_{ind} + β θ_{dep} = K θ

(Gautier, "Numerical calculation of the base inertial parameters of robots", 1991). ``K`` is
``r x p``; its rows are printed as readable groupings such as ``Izz2 + a2**2*(m2 + m3)`` when the
numerical coefficients match products of the robot's named lengths.

A base parameter is named after the standard parameter it leads with, plus ``R`` when others
are regrouped into it (Khalil's convention, e.g. ``Izz2R``).
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

RANK_TOLERANCE = 1e-9
_COEFFICIENT_TOLERANCE = 1e-9


@dataclass(frozen=True)
class BaseParameters:
    """The base-parameter reduction of one model.

    Attributes
    ----------
    independent, dependent
        Column indices (into the standard parameters) kept, and regrouped or dropped.
    beta
        ``r x (p − r)``: ``Y[:, dependent] = Y[:, independent] @ beta``.
    K
        ``r x p`` matrix from standard to base parameters, ``θ_base = K θ``.
    names
        Name of each base parameter.
    expressions
        Readable grouping of each base parameter in standard parameters.
    unidentifiable
        Standard parameters with no effect at all on this model (zero columns).
    """

    independent: tuple[int, ...]
    dependent: tuple[int, ...]
    beta: NDArray[np.float64]
    K: NDArray[np.float64]
    names: tuple[str, ...]
    expressions: tuple[str, ...]
    unidentifiable: tuple[str, ...]

    @property
    def n_base(self) -> int:
        return len(self.independent)

    def to_base(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        """``θ_base = K θ``."""
        theta = np.asarray(theta, dtype=float)
        if theta.shape[-1] != self.K.shape[1]:
            raise ValueError(f"expected {self.K.shape[1]} standard parameters, got {theta.shape[-1]}")
        return theta @ self.K.T


def reduce_to_base(
    stacked_regressor: NDArray[np.float64],
    parameter_names: Sequence[str],
    *,
    geometry: Mapping[str, float] | None = None,
    tolerance: float = RANK_TOLERANCE,
) -> BaseParameters:
    """Find the base parameters from a regressor stacked over generic random states.

    Parameters
    ----------
    stacked_regressor
        ``(rows, p)``: the regressor evaluated at enough random states (rows ≫ p).
    parameter_names
        The ``p`` standard parameter names.
    geometry
        Named lengths for printing coefficients (``{"a2": 0.4318, ...}``).
    tolerance
        Relative tolerance on ``|R_kk| / |R_00|`` for the numerical rank.
    """
    Y = np.asarray(stacked_regressor, dtype=float)
    n_rows, n_parameters = Y.shape
    if len(parameter_names) != n_parameters:
        raise ValueError(f"{len(parameter_names)} names for {n_parameters} columns")
    if n_rows < n_parameters:
        raise ValueError(f"need at least as many rows as parameters ({n_rows} < {n_parameters})")
    norms = np.linalg.norm(Y, axis=0)
    scale_reference = norms.max()
    zero = norms <= 1e-12 * scale_reference
    scaled = Y / np.where(zero, 1.0, norms)
    scaled[:, zero] = 0.0
    # Rank from a pivoted (rank-revealing) QR; leaders chosen in a physical priority order by an
    # unpivoted QR of the reordered columns: a column is dependent when it lies in the span of the
    # columns before it.
    pivoted_r = scipy.linalg.qr(scaled, mode="r", pivoting=True)[0]
    pivoted_diagonal = np.abs(np.diag(pivoted_r))
    rank = int(np.sum(pivoted_diagonal > tolerance * pivoted_diagonal[0]))
    order = sorted(range(n_parameters), key=lambda column: _priority(parameter_names[column], column))
    ordered_r = scipy.linalg.qr(scaled[:, order], mode="r")[0]
    diagonal = np.abs(np.diag(ordered_r))
    leaders = [order[k] for k in range(n_parameters) if diagonal[k] > tolerance * pivoted_diagonal[0]]
    if len(leaders) != rank:
        raise RuntimeError(
            f"base-parameter reduction: ordered QR found {len(leaders)} independent columns, pivoted QR {rank}"
        )
    independent = np.sort(np.array(leaders, dtype=int))
    dependent = np.setdiff1d(np.arange(n_parameters), independent)
    beta, *_ = np.linalg.lstsq(Y[:, independent], Y[:, dependent], rcond=None)
    beta[np.abs(beta) < 1e-10 * max(1.0, np.abs(beta).max(initial=0.0))] = 0.0
    residual = np.linalg.norm(Y[:, independent] @ beta - Y[:, dependent]) / max(np.linalg.norm(Y), 1e-300)
    if residual > 1e-8:
        raise RuntimeError(f"base-parameter reduction is inconsistent (relative residual {residual:.2e})")
    K = np.zeros((rank, n_parameters))
    K[np.arange(rank), independent] = 1.0
    K[:, dependent] = beta
    names, expressions = _describe(K, independent, parameter_names, geometry or {})
    return BaseParameters(
        independent=tuple(int(i) for i in independent),
        dependent=tuple(int(i) for i in dependent),
        beta=beta,
        K=K,
        names=tuple(names),
        expressions=tuple(expressions),
        unidentifiable=tuple(parameter_names[i] for i in np.flatnonzero(zero)),
    )


_INERTIA_ORDER = ("Izz", "Ixx", "Iyy", "Ixy", "Ixz", "Iyz")
_MOMENT_ORDER = ("mx", "my", "mz")


def _priority(name: str, column: int) -> tuple[int, int, int]:
    """Leader preference: plate offsets, inertias, first moments, masses, then joint effects.

    This reproduces the groupings of the PUMA paper's Tables III–V (masses and far-link terms
    regrouped into inertias and first moments of nearer links).
    """
    match = re.fullmatch(r"(Ixx|Ixy|Iyy|Ixz|Iyz|Izz|mx|my|mz|m)(\d+)", name)
    if match is None:
        # plate offsets lead (they absorb the static weight); joint effects such as armature are
        # regrouped into the inertias they cannot be told apart from
        return (0, 0, column) if name.endswith("_off") else (4, 0, column)
    kind, link = match.group(1), int(match.group(2))
    if kind in _INERTIA_ORDER:
        return (1, link, _INERTIA_ORDER.index(kind))
    if kind in _MOMENT_ORDER:
        return (2, link, _MOMENT_ORDER.index(kind))
    return (3, -link, 0)


def _link_index(name: str) -> int | None:
    match = re.search(r"(\d+)$", name)
    return int(match.group(1)) if match else None


def _monomials(geometry: Mapping[str, float]) -> list[tuple[str, float, tuple[int, ...]]]:
    """Products of up to two named lengths: (text, value, indices), simplest first."""
    symbols = sorted(geometry.items(), key=lambda item: (_link_index(item[0]) or 0, item[0]))
    monomials = [(name, value, (_link_index(name) or 0,)) for name, value in symbols]
    for (name_a, value_a), (name_b, value_b) in itertools.combinations_with_replacement(symbols, 2):
        text = f"{name_a}**2" if name_a == name_b else f"{name_a}*{name_b}"
        monomials.append((text, value_a * value_b, (_link_index(name_a) or 0, _link_index(name_b) or 0)))
    return monomials


def _coefficient_text(
    value: float, monomials: list[tuple[str, float, tuple[int, ...]]], link_range: tuple[int, int]
) -> str:
    """``value`` as ``[-][k*]monomial`` or a sum of two, preferring lengths of the links involved."""
    if abs(value - 1.0) < _COEFFICIENT_TOLERANCE:
        return "1"
    if abs(value + 1.0) < _COEFFICIENT_TOLERANCE:
        return "-1"
    low, high = link_range

    def penalty(indices: tuple[int, ...]) -> int:
        return sum(0 if low <= index <= high else 1 for index in indices)

    candidates: list[tuple[int, int, str]] = []
    tolerance = _COEFFICIENT_TOLERANCE * max(1.0, abs(value))
    for factor in (1, 2):
        for text, monomial, indices in monomials:
            for sign in (1, -1):
                if abs(sign * factor * monomial - value) < tolerance:
                    prefix = ("-" if sign < 0 else "") + (f"{factor}*" if factor != 1 else "")
                    candidates.append((penalty(indices), len(indices), prefix + text))
    if not candidates:
        for (text_a, value_a, indices_a), (text_b, value_b, indices_b) in itertools.combinations(monomials, 2):
            for sign_a, sign_b in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
                if abs(sign_a * value_a + sign_b * value_b - value) < tolerance:
                    text = ("-" if sign_a < 0 else "") + text_a + (" - " if sign_b < 0 else " + ") + text_b
                    candidates.append((penalty(indices_a + indices_b), 4, f"({text})"))
    if candidates:
        return min(candidates)[2]
    return f"{value:.6g}"


def _describe(
    K: NDArray[np.float64], independent: NDArray[np.int_], parameter_names: Sequence[str], geometry: Mapping[str, float]
) -> tuple[list[str], list[str]]:
    monomials = _monomials(geometry)
    names, expressions = [], []
    for row, leader in zip(K, independent):
        leader_name = parameter_names[leader]
        groups: dict[str, list[str]] = {}
        for column in np.flatnonzero(row):
            if column == leader:
                continue
            links = [index for index in (_link_index(leader_name), _link_index(parameter_names[column])) if index]
            link_range = (min(links), max(links)) if links else (0, 0)
            coefficient = _coefficient_text(float(row[column]), monomials, link_range)
            groups.setdefault(coefficient, []).append(parameter_names[column])
        terms = [leader_name]
        for coefficient, members in groups.items():
            negative = coefficient.startswith("-") and not coefficient.startswith("-(")
            magnitude = coefficient[1:] if negative else coefficient
            sign = "- " if negative else "+ "
            if magnitude == "1":
                terms.extend(sign + member for member in members)
                continue
            body = members[0] if len(members) == 1 else "(" + " + ".join(members) + ")"
            terms.append(f"{sign}{magnitude}*{body}")
        names.append(leader_name + ("R" if len(terms) > 1 else ""))
        expressions.append(" ".join(terms))
    return names, expressions


def random_states(
    n_joints: int, n_samples: int, *, seed: int = 0, prismatic: Sequence[bool] | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Generic joint states for the reduction: angles uniform in ``[-π, π]`` (±1 m for prismatic)."""
    generator = np.random.default_rng(seed)
    q = generator.uniform(-np.pi, np.pi, (n_samples, n_joints))
    if prismatic is not None:
        q[:, np.asarray(prismatic, dtype=bool)] /= np.pi
    dq = generator.normal(0.0, 1.0, (n_samples, n_joints))
    ddq = generator.normal(0.0, 1.0, (n_samples, n_joints))
    return q, dq, ddq


