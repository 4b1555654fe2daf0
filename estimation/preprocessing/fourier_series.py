"""Finite Fourier series of a periodic motion (PUMA paper, eq. 18): evaluation and least-squares fit.

.. math::
    q_i(t) = q_{0,i} + \\sum_{l=1}^{N} \\frac{a_{i,l}}{ω_f l} \\sin(ω_f l t) - \\frac{b_{i,l}}{ω_f l} \\cos(ω_f l t)

The contract shared by the excitation design (:mod:`oed.fourier`, which builds on it) and the
differentiation of measured positions (:mod:`estimation.preprocessing.differentiation`). The fit is linear least
squares on the samples' own time stamps: any fundamental, any sampling (jittered, float32 stamps),
any record length of at least one period works; no whole number of samples per period is needed.
The derivatives of measured positions are fitted many times a run (every harmonic count the preprocessing choice
scores, then each record): there the fit solves the equilibrated normal equations (``solver="normal"``), to
rounding what the SVD gives; on a regular grid of time stamps their sums, and the evaluation of a long series, are
chirp z-transforms (:mod:`estimation.preprocessing.fourier_sums`), never the design; the frequency search and the
excitation design keep the SVD.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from estimation.preprocessing.fourier_sums import UniformFourierSums


#: elements of the ``(T, N)`` phase array evaluated at once: 60 000 samples of 400 harmonics took 1.2 GB whole
EVALUATION_BLOCK = 1 << 20
#: the normal equations of a fit are solved when the reciprocal condition number of their equilibrated matrix
#: is above this (a coefficient error of order ``eps/rcond``, below 1e-10 relative); the SVD otherwise
NORMAL_RCOND = 1e-6

#: samples times harmonics from which a series on a regular grid is evaluated by chirp z-transforms
UNIFORM_EVALUATION = 1 << 16

Solver = Literal["svd", "normal"]


def evaluate_series(frequency_hz: float, q0: NDArray[np.float64], a: NDArray[np.float64], b: NDArray[np.float64],
                    t: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """``q, dq, ddq`` of eq. 18 at times ``t``, each ``(len(t), n)``; ``q0 (n,)``, ``a, b (n, N)``: on a regular
    grid of at least :data:`UNIFORM_EVALUATION` samples times harmonics by chirp z-transforms
    (:class:`~estimation.preprocessing.fourier_sums.UniformFourierSums`), else in blocks of samples
    (:data:`EVALUATION_BLOCK`), so that memory stays bounded whatever the record's length."""
    t = np.asarray(t, dtype=float).reshape(-1)
    omega = 2 * np.pi * frequency_hz * np.arange(1, a.shape[1] + 1)  # (N,)
    sums = UniformFourierSums.of(t, frequency_hz, a.shape[1], origin=0.0) \
        if t.shape[0] * a.shape[1] >= UNIFORM_EVALUATION else None
    if sums is not None:  # the three series at once, in the basis [1, sin ω_l t, cos ω_l t]
        n = a.shape[0]
        coefficients = np.zeros((2 * a.shape[1] + 1, 3 * n))
        coefficients[0, :n] = q0
        coefficients[1:, :n] = np.vstack([(a / omega).T, (-b / omega).T])
        coefficients[1:, n:2 * n] = np.vstack([b.T, a.T])
        coefficients[1:, 2 * n:] = np.vstack([(-a * omega).T, (b * omega).T])
        values = sums.fitted(coefficients)
        return values[:, :n], values[:, n:2 * n], values[:, 2 * n:]
    q, dq, ddq = (np.empty((t.shape[0], a.shape[0])) for _ in range(3))
    rows = max(1, EVALUATION_BLOCK // max(a.shape[1], 1))
    for start in range(0, t.shape[0], rows):
        block = slice(start, start + rows)
        phase = np.outer(t[block], omega)  # (rows, N)
        sin = np.sin(phase)
        cos = np.cos(phase, out=phase)
        scaled = sin / omega  # one buffer for the four scaled bases, each used once
        q[block] = q0 + scaled @ a.T - np.divide(cos, omega, out=scaled) @ b.T
        dq[block] = cos @ a.T + sin @ b.T
        ddq[block] = np.multiply(sin, -omega, out=scaled) @ a.T + np.multiply(cos, omega, out=scaled) @ b.T
    return q, dq, ddq


def design_matrix(t: ArrayLike, frequency_hz: float, harmonics: int) -> NDArray[np.float64]:
    """``(T, 2N+1)`` columns ``[1, sin(ω_l t)/ω_l, −cos(ω_l t)/ω_l]``: ``q = D [q0; a; b]`` (eq. 18)."""
    t = np.asarray(t, dtype=float).reshape(-1)
    omega = 2 * np.pi * frequency_hz * np.arange(1, harmonics + 1)
    phase = np.outer(t, omega)
    design = np.empty((t.shape[0], 2 * harmonics + 1))  # filled in place: no (T, N) temporaries
    design[:, 0] = 1.0
    np.divide(np.sin(phase), omega, out=design[:, 1:harmonics + 1])
    np.divide(np.cos(phase, out=phase), -omega, out=design[:, harmonics + 1:])
    return design


@dataclass(frozen=True)
class FourierSeries:
    """Coefficients of eq. 18 for ``n`` joints and ``N`` harmonics of ``frequency_hz``.

    Attributes
    ----------
    frequency_hz
        Fundamental, Hz.
    q0
        ``(n,)`` offsets.
    a, b
        ``(n, N)`` coefficients (velocity amplitudes).
    """

    frequency_hz: float
    q0: NDArray[np.float64]
    a: NDArray[np.float64]
    b: NDArray[np.float64]

    @property
    def harmonics(self) -> int:
        return int(np.shape(self.a)[1])

    def evaluate(self, t: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """``q, dq, ddq`` at times ``t`` (eq. 18)."""
        return evaluate_series(self.frequency_hz, np.asarray(self.q0), np.atleast_2d(self.a), np.atleast_2d(self.b), t)

    def to_dict(self) -> dict[str, Any]:
        return {"frequency_hz": float(self.frequency_hz), "harmonics": self.harmonics,
                "q0": np.asarray(self.q0).tolist(), "a": np.asarray(self.a).tolist(), "b": np.asarray(self.b).tolist()}


def fit_series(t: ArrayLike, q: ArrayLike, frequency_hz: float, harmonics: int, *,
               solver: Solver = "svd") -> tuple[FourierSeries, float]:
    """Least-squares fit of eq. 18 to positions ``q (T, n)`` sampled at ``t``; returns the series and
    the residual sum of squares over all joints.

    ``solver``: ``"svd"`` (``numpy.linalg.lstsq``) or ``"normal"``: the normal equations equilibrated to a unit
    diagonal, by Cholesky (:func:`normal_solution`; over a period the basis is near-orthogonal and their
    condition number a few units: 2–4 times faster than the SVD at 80–400 harmonics), the SVD where they are
    not well conditioned."""
    t = np.asarray(t, dtype=float).reshape(-1)
    q = np.asarray(q, dtype=float).reshape(t.shape[0], -1)
    if int(harmonics) != harmonics or harmonics < 1:
        raise ValueError(f"harmonics must be at least 1, got {harmonics}")
    check_determined(t.shape[0], harmonics)
    fitted = uniform_fit(t, q, frequency_hz, harmonics) if solver == "normal" else None
    if fitted is None:
        design = design_matrix(t - t[0], frequency_hz, harmonics)  # phases from the record's start: well scaled
        coefficients = normal_solution(design, q) if solver == "normal" else None
        if coefficients is None:
            coefficients = np.linalg.lstsq(design, q, rcond=None)[0]  # (2N+1, n)
        residual = float(np.sum((q - design @ coefficients) ** 2))
    else:
        coefficients, residual = fitted
    return series_at_origin(coefficients, float(t[0]), frequency_hz, harmonics), residual


def series_at_origin(coefficients: NDArray[np.float64], origin: float, frequency_hz: float,
                     harmonics: int) -> FourierSeries:
    """The series of the coefficients ``(2N+1, n)`` of :func:`design_matrix` ``(t − origin)``, in absolute time: a
    phase shift ``ω_l origin`` rotates ``(a_l, b_l)``."""
    omega = 2 * np.pi * frequency_hz * np.arange(1, harmonics + 1)
    sine, cosine = coefficients[1:1 + harmonics].T, coefficients[1 + harmonics:].T  # coefficients at t - origin
    c, s = np.cos(omega * origin), np.sin(omega * origin)
    # sin(ω(t−t0)) = sin ωt cos ωt0 − cos ωt sin ωt0 ; −cos(ω(t−t0)) = −cos ωt cos ωt0 − sin ωt sin ωt0
    a = sine * c - cosine * s
    b = sine * s + cosine * c
    return FourierSeries(float(frequency_hz), coefficients[0], a, b)


class SummedFourierFit:
    """The least-squares fit of eq. 18 to positions given block by block (a record read in chunks, never held
    whole): the normal equations of :func:`design_matrix` ``(t − origin)`` summed over the blocks
    (:meth:`add`), solved as :func:`fit_series` ``(solver="normal")`` solves them (:func:`gram_solution`), with
    ``origin`` the record's first time stamp as there. Their sums are those of the whole record, so the series is
    :func:`fit_series`'s to rounding, on any time stamps. When they are not well conditioned (:meth:`series` gives
    ``None``), :class:`TriangularFourierFit` over a second pass is the SVD's answer. Memory: ``(2N+1)²`` floats."""

    def __init__(self, frequency_hz: float, harmonics: int, origin: float, n_joints: int) -> None:
        if int(harmonics) != harmonics or harmonics < 1:
            raise ValueError(f"harmonics must be at least 1, got {harmonics}")
        width = 2 * int(harmonics) + 1
        self.frequency_hz, self.harmonics, self.origin = float(frequency_hz), int(harmonics), float(origin)
        self.gram, self.moment, self.n_samples = np.zeros((width, width)), np.zeros((width, n_joints)), 0

    def add(self, t: ArrayLike, q: ArrayLike) -> None:
        """Add the samples ``q (T, n)`` at ``t``."""
        t = np.asarray(t, dtype=float).reshape(-1)
        design = design_matrix(t - self.origin, self.frequency_hz, self.harmonics)
        self.gram += design.T @ design
        self.moment += design.T @ np.asarray(q, dtype=float).reshape(t.shape[0], -1)
        self.n_samples += t.shape[0]

    def series(self) -> FourierSeries | None:
        """The fitted series, or ``None`` when the normal equations are not well conditioned."""
        check_determined(self.n_samples, self.harmonics)
        coefficients = gram_solution(self.gram, self.moment)
        return None if coefficients is None else series_at_origin(coefficients, self.origin, self.frequency_hz,
                                                                  self.harmonics)


class TriangularFourierFit:
    """:class:`SummedFourierFit` by the triangular factor of ``[D | q]`` updated block by block (Householder QR of
    the factor so far stacked on each block, Golub & Van Loan, *Matrix Computations*, section 5.3): ``min ‖D x −
    q‖`` is ``min ‖R₁₁ x − R₁₂‖`` whatever the conditioning, whose least-squares solution of least norm is the
    SVD's on the record (:func:`numpy.linalg.lstsq`, :func:`fit_series`'s fallback). Memory: ``(2N+1+n)²``
    floats."""

    def __init__(self, frequency_hz: float, harmonics: int, origin: float, n_joints: int) -> None:
        self.frequency_hz, self.harmonics, self.origin = float(frequency_hz), int(harmonics), float(origin)
        self.factor, self.n_samples = np.zeros((0, 2 * self.harmonics + 1 + n_joints)), 0

    def add(self, t: ArrayLike, q: ArrayLike) -> None:
        """Add the samples ``q (T, n)`` at ``t``."""
        t = np.asarray(t, dtype=float).reshape(-1)
        design = design_matrix(t - self.origin, self.frequency_hz, self.harmonics)
        block = np.hstack([design, np.asarray(q, dtype=float).reshape(t.shape[0], -1)])
        self.factor = scipy.linalg.qr(np.vstack([self.factor, block]), mode="r")[0][:block.shape[1]]
        self.n_samples += t.shape[0]

    def series(self) -> FourierSeries:
        """The fitted series."""
        check_determined(self.n_samples, self.harmonics)
        width = 2 * self.harmonics + 1
        coefficients = np.linalg.lstsq(self.factor[:width, :width], self.factor[:width, width:], rcond=None)[0]
        return series_at_origin(coefficients, self.origin, self.frequency_hz, self.harmonics)


def check_determined(n_samples: int, harmonics: int) -> None:
    """``ValueError`` when ``n_samples`` cannot determine the ``2 harmonics + 1`` coefficients of a joint."""
    if n_samples < 2 * harmonics + 1:
        raise ValueError(f"{n_samples} samples cannot determine {2 * harmonics + 1} Fourier coefficients per joint")


def uniform_fit(t: NDArray[np.float64], q: NDArray[np.float64], frequency_hz: float,
                harmonics: int) -> tuple[NDArray[np.float64], float] | None:
    """The coefficients of :func:`design_matrix` ``(t − t0)`` fitted to ``q`` from the normal equations and the
    residual sum of squares, each sum a chirp z-transform (:class:`~estimation.preprocessing.fourier_sums.
    UniformFourierSums`): ``None`` when the time stamps are not on a regular grid or the equations are not well
    conditioned (:func:`gram_solution`)."""
    sums = UniformFourierSums.of(t, frequency_hz, harmonics, origin=float(t[0]))
    if sums is None:
        return None
    omega = 2 * np.pi * frequency_hz * np.arange(1, harmonics + 1)
    scale = np.concatenate([[1.0], 1.0 / omega, -1.0 / omega])  # the design's columns are the plain basis scaled
    normal, moment = sums.normal_equations(q)
    coefficients = gram_solution(normal * np.outer(scale, scale), moment * scale[:, None])
    if coefficients is None:
        return None
    return coefficients, float(np.sum((q - sums.fitted(coefficients * scale[:, None])) ** 2))


def normal_solution(design: NDArray[np.float64], values: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """The least-squares coefficients of ``values ≈ design · x`` from the normal equations (:func:`gram_solution`),
    or ``None`` when they are not well conditioned."""
    return gram_solution(design.T @ design, design.T @ values)


def gram_solution(gram: NDArray[np.float64], right: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """The solution of the normal equations ``gram · x = right`` equilibrated to a unit diagonal (Cholesky), or
    ``None`` when their reciprocal condition number (LAPACK ``dpocon``, 1-norm) is below :data:`NORMAL_RCOND` or
    the factorisation fails (the caller then takes the SVD)."""
    scale = np.sqrt(np.diag(gram))
    if not np.all(np.isfinite(scale)) or np.any(scale == 0):
        return None
    equilibrated = gram / np.outer(scale, scale)
    factor, info = scipy.linalg.lapack.dpotrf(equilibrated, lower=False)
    if info != 0:
        return None
    rcond, info = scipy.linalg.lapack.dpocon(factor, np.max(np.sum(np.abs(equilibrated), axis=0)))  # upper factor
    if info != 0 or not rcond >= NORMAL_RCOND:
        return None
    right = np.asarray(right, dtype=float).reshape(gram.shape[0], -1) / scale[:, None]
    return scipy.linalg.cho_solve((factor, False), right, check_finite=False) / scale[:, None]
