"""Recursive least squares (RLS) and extended recursive least squares (ERLS, ARMAX) with forgetting factor.

The recursion at sample ``n`` (Åström & Wittenmark; the servo paper's eqs. 22–25), with
``φ(n)`` from :mod:`estimation.estimators.arx` and forgetting factor ``λ``::

    e(n)   = y(n) − φ(n)ᵀ θ(n−1)                       a-priori prediction error
    g(n)   = P(n−1) φ(n) / (λ + φ(n)ᵀ P(n−1) φ(n))
    θ(n)   = θ(n−1) + g(n) e(n)
    P(n)   = (P(n−1) − g(n) φ(n)ᵀ P(n−1)) / λ,  then symmetrised: P ← (P + Pᵀ)/2
    ε(n)   = y(n) − φ(n)ᵀ θ(n)                         residual standing in for the noise (eq. 23)

RLS is the same recursion with ``nc = 0`` (no ``ε`` in the regressor). Two back ends compute it:

* ``"numpy"``: a per-sample Python loop (the reference; can keep per-sample histories when asked);
* ``"compiled"``: the step as a CasADi graph, ``mapaccum`` over blocks of samples, generated C code
  (:mod:`estimation.codegen`, falls back to the CasADi VM without a compiler). Only the state at the end
  of each chunk of ``CHUNK`` samples is returned, so no per-sample covariance history is kept.

Examples
--------
>>> import numpy as np
>>> from estimation.estimators.arx import ARXEstimator
>>> from estimation.estimators.recursive import ExtendedRecursiveLeastSquares
>>> rng = np.random.default_rng(1)
>>> u, e = rng.standard_normal(20000), 0.1 * rng.standard_normal(20000)
>>> y = ARXEstimator.simulate_structure(a=[-1.5, 0.7], b=[1.0], c=[0.5], nk=1, u=u, e=e)
>>> erls = ExtendedRecursiveLeastSquares(na=2, nb=1, nc=1).fit(u, y)
>>> bool(np.allclose(erls.theta_, [-1.5, 0.7, 1.0, 0.5], atol=0.03))
True
"""

from __future__ import annotations

import functools
import warnings
from typing import Literal

import casadi
import numpy as np
import scipy.signal
from numpy.typing import ArrayLike

from estimation.estimators.arx import Polynomials, as_signal_pair, check_orders
from estimation.estimators.errors import NotFittedError
from dynamics.signal_checks import check_informative, rank_deficiency_message
from estimation.estimators.estimator import Estimator
from dynamics.codegen.compiled import compile_function

Backend = Literal["compiled", "numpy", "vm"]
CHUNK = 256  # samples per inner mapaccum; the state is returned once per chunk
CHUNKS_PER_BLOCK = 64  # chunks per call of the compiled block (16 384 samples)


class CovarianceBlowUpWarning(RuntimeWarning):
    """The trace of ``P`` exceeded ``max_trace``: the recursion is winding up (poor excitation with λ < 1)."""


class RecursionDivergedError(ValueError):
    """``θ`` or ``P`` became NaN/inf: the recursion diverged (covariance blow-up)."""


def _layout(na: int, nb: int, nk: int, nc: int) -> dict[str, slice]:
    p = na + nb + nc
    sizes = (("theta", p), ("P", p * p), ("y", na), ("u", nk + nb - 1), ("eps", nc))
    layout, start = {}, 0
    for name, size in sizes:
        layout[name] = slice(start, start + size)
        start += size
    layout["size"] = slice(0, start)
    return layout


def _head(v: casadi.SX, n: int) -> casadi.SX:
    """First ``n`` entries of a column (``n = 0`` gives an empty column, unlike ``v[:0]``)."""
    return v[:n] if n > 0 else casadi.SX(0, 1)


@functools.cache
def erls_step_function(na: int, nb: int, nk: int, nc: int, forgetting: float) -> casadi.Function:
    """One ERLS step (eqs. 23–25) as ``casadi.Function`` ``erls_step``: ``(x, d) -> (x_next, e)``.

    ``x`` stacks ``θ``, ``P`` (column-major), past ``y``, past ``u`` and past ``ε``; ``d = [y(n), u(n), w(n)]``
    with ``w = 1`` for a real sample and ``w = 0`` for padding (state unchanged, ``e = 0``).
    """
    lay = _layout(na, nb, nk, nc)
    p = na + nb + nc
    x = casadi.SX.sym("x", lay["size"].stop)
    d = casadi.SX.sym("d", 3)
    theta, P = x[lay["theta"]], casadi.reshape(x[lay["P"]], p, p)
    ymem, umem, emem = x[lay["y"]], x[lay["u"]], x[lay["eps"]]
    y, u, w = d[0], d[1], d[2]
    umem_now = casadi.vertcat(u, umem)  # u(n), u(n-1), ...
    phi = casadi.vertcat(-ymem, umem_now[nk : nk + nb], emem)
    e = y - casadi.dot(phi, theta)
    p_phi = casadi.mtimes(P, phi)
    g = p_phi / (forgetting + casadi.dot(phi, p_phi))
    theta_next = theta + g * e
    P_next = (P - casadi.mtimes(g, p_phi.T)) / forgetting
    P_next = 0.5 * (P_next + P_next.T)  # keep P symmetric: without this, round-off makes it indefinite when λ < 1
    eps = y - casadi.dot(phi, theta_next)
    x_upd = casadi.vertcat(
        theta_next, casadi.vec(P_next), _head(casadi.vertcat(y, ymem), na), _head(umem_now, nk + nb - 1), _head(casadi.vertcat(eps, emem), nc)
    )
    x_next = w * x_upd + (1 - w) * x
    return casadi.Function("erls_step", [x, d], [x_next, w * e], ["x", "d"], ["x_next", "e"])


@functools.cache
def erls_block_function(na: int, nb: int, nk: int, nc: int, forgetting: float, backend: Backend) -> casadi.Function:
    """``CHUNK × CHUNKS_PER_BLOCK`` ERLS steps; outputs the state at each chunk end and every ``e(n)``."""
    step = erls_step_function(na, nb, nk, nc, forgetting)
    inner = step.mapaccum("erls_chunk_steps", CHUNK)
    x0 = casadi.MX.sym("x", step.size1_in(0))
    data = casadi.MX.sym("d", 3, CHUNK)
    states, errors = inner(x0, data)
    chunk = casadi.Function("erls_chunk", [x0, data], [states[:, CHUNK - 1], errors], ["x", "d"], ["x_next", "e"])
    tag = f"{na}_{nb}_{nk}_{nc}_{np.float64(forgetting).hex().replace('.', 'p').replace('-', 'm').replace('+', '')}"
    block = chunk.mapaccum(f"erls_block_{tag}", CHUNKS_PER_BLOCK)
    if backend == "compiled":
        return compile_function(block)
    return block


def _numpy_run(x: np.ndarray, data: np.ndarray, na: int, nb: int, nk: int, nc: int, lam: float, history: bool):
    """Reference per-sample loop; returns final state, e(n), chunk-end traces and optional histories."""
    lay = _layout(na, nb, nk, nc)
    p = na + nb + nc
    theta = x[lay["theta"]].copy()
    P = x[lay["P"]].reshape(p, p, order="F").copy()
    ymem, umem, emem = x[lay["y"]].copy(), x[lay["u"]].copy(), x[lay["eps"]].copy()
    n = data.shape[0]
    errors = np.zeros(n)
    traces = []
    theta_hist = np.zeros((n, p)) if history else None
    P_hist = np.zeros((n, p, p)) if history else None
    for i in range(n):
        y, u = data[i, 0], data[i, 1]
        umem_now = np.concatenate(([u], umem))
        phi = np.concatenate((-ymem, umem_now[nk : nk + nb], emem))
        e = y - phi @ theta
        p_phi = P @ phi
        g = p_phi / (lam + phi @ p_phi)
        theta = theta + g * e
        P = (P - np.outer(g, p_phi)) / lam
        P = 0.5 * (P + P.T)
        eps = y - phi @ theta
        ymem = np.concatenate(([y], ymem))[:na]
        umem = umem_now[: nk + nb - 1]
        emem = np.concatenate(([eps], emem))[:nc]
        errors[i] = e
        if history:
            theta_hist[i], P_hist[i] = theta, P
        if (i + 1) % CHUNK == 0 or i + 1 == n:
            traces.append(np.trace(P))
    state = np.concatenate((theta, P.reshape(-1, order="F"), ymem, umem, emem))
    return state, errors, np.asarray(traces), theta_hist, P_hist


class RecursiveLeastSquares(Estimator):
    """Recursive least squares for ARX models, with forgetting factor (ERLS with ``nc = 0``).

    Parameters
    ----------
    na, nb, nk
        Model orders and input delay (samples).
    forgetting
        Forgetting factor ``λ ∈ (0, 1]``.
    delta
        Initial covariance ``P(0) = δ I``.
    backend
        ``"compiled"`` (generated C, default), ``"vm"`` (CasADi virtual machine) or ``"numpy"`` (reference loop).
    keep_history
        Keep ``theta_history_`` and ``P_history_`` per sample (``backend="numpy"`` only).
    max_trace
        Warn with :class:`CovarianceBlowUpWarning` when ``trace P`` exceeds this at a chunk end.
    """

    nc_fixed: int | None = 0

    def __init__(
        self, *, na: int = 2, nb: int = 1, nk: int = 1, forgetting: float = 1.0, delta: float = 1e4,
        backend: Backend = "compiled", keep_history: bool = False, max_trace: float = 1e12,
    ) -> None:
        self.na = na
        self.nb = nb
        self.nk = nk
        self.forgetting = forgetting
        self.delta = delta
        self.backend = backend
        self.keep_history = keep_history
        self.max_trace = max_trace

    @property
    def _nc(self) -> int:
        return 0

    def _validate(self) -> None:
        check_orders(self.na, self.nb, self.nk, self._nc)
        if not (0.0 < self.forgetting <= 1.0):
            raise ValueError(f"forgetting factor must be in (0, 1], got {self.forgetting!r}")
        if not (self.delta > 0 and np.isfinite(self.delta)):
            raise ValueError(f"delta (initial covariance scale) must be positive, got {self.delta!r}")
        if self.backend not in ("compiled", "vm", "numpy"):
            raise ValueError(f"backend must be 'compiled', 'vm' or 'numpy', got {self.backend!r}")
        if self.keep_history and self.backend != "numpy":
            raise ValueError("keep_history=True needs backend='numpy' (the compiled recursion keeps no per-sample history)")

    def fit(self, u: ArrayLike, y: ArrayLike) -> RecursiveLeastSquares:
        """Run the recursion over the record; sets ``theta_``, ``P_``, ``cov_``, ``noise_variance_``,
        ``prediction_errors_`` (a-priori ``e(n)``) and ``trace_`` (``trace P`` at each chunk end).

        The recursion sees u and y scaled to unit RMS (``delta``, ``max_trace`` and ``trace_`` are
        in those units); ``theta_``, ``P_`` and the histories are given back in the data's units.

        Raises
        ------
        RecursionDivergedError
            If ``θ`` or ``P`` become NaN/inf (names the chunk where it happened).
        """
        self._forget_fit()
        self._validate()
        u, y = as_signal_pair(u, y)
        check_informative(u, y)
        na, nb, nk, nc = self.na, self.nb, self.nk, self._nc
        p = na + nb + nc
        if y.size <= p:
            raise ValueError(f"{y.size} samples for {p} parameters: the recursion needs more data")
        lay = _layout(na, nb, nk, nc)
        x0 = np.zeros(lay["size"].stop)
        x0[lay["P"]] = (self.delta * np.eye(p)).reshape(-1)
        # The recursion runs on u and y scaled to unit RMS, so that P(0) = δ I is large against the
        # data whatever their units (on y 1e-4 against u 1e4 it shrank a1 from -0.5 to -0.2);
        # a and c are unit-free, b scales by y_rms / u_rms.
        u_rms, y_rms = float(np.sqrt(np.mean(u**2))), float(np.sqrt(np.mean(y**2)))
        unscale = np.concatenate([np.ones(na), np.full(nb, y_rms / u_rms), np.ones(nc)])
        data = np.column_stack((y / y_rms, u / u_rms, np.ones_like(y)))
        # The first update is at the first sample whose regressor holds measured values only; the
        # samples before it fill the memories (zeros there made the first rows outliers whenever
        # the signals do not start at 0, and RLS then missed batch ARX by far).
        first = max(na, nk + nb - 1)
        memory = nk + nb - 1
        x0[lay["y"]] = data[first - na:first, 0][::-1]
        x0[lay["u"]] = data[first - memory:first, 1][::-1]
        if self.backend == "numpy":
            state, errors, traces, theta_hist, P_hist = _numpy_run(x0, data[first:], na, nb, nk, nc,
                                                                   float(self.forgetting), self.keep_history)
            if self.keep_history:
                theta_hist = np.vstack([np.zeros((first, p)), theta_hist])
                P_hist = np.concatenate([np.broadcast_to(self.delta * np.eye(p), (first, p, p)), P_hist])
                self.theta_history_ = theta_hist * unscale
                self.P_history_ = P_hist * np.outer(unscale, unscale)
        else:
            state, errors, traces = self._block_run(x0, data[first:])
        errors = np.concatenate([np.zeros(first), errors])  # no prediction before the first update
        self._check_divergence(state[lay["theta"]], traces)
        self.theta_ = state[lay["theta"]] * unscale
        self.P_ = state[lay["P"]].reshape(p, p, order="F") * np.outer(unscale, unscale)
        errors = errors * y_rms
        self.prediction_errors_ = errors
        self.trace_ = traces
        tail = errors[errors.size // 2 :]
        self.noise_variance_ = float(tail @ tail) / max(tail.size - p, 1)
        self.n_parameters_ = p
        try:
            self.cov_ = self._prediction_error_covariance(u, y)
        except ValueError:
            self._forget_fit()  # no half-fitted estimator
            raise
        return self

    def _prediction_error_covariance(self, u: np.ndarray, y: np.ndarray) -> np.ndarray:
        """``σ² (Σ ψ ψᵀ)⁻¹`` with ``ψ = −∂ε/∂θ = φ / C(q)`` at the final ``θ`` (λ = 1).

        The prediction-error estimator's asymptotic covariance (Ljung, *System Identification*,
        eq. 9.17). For ARX (``C = 1``) it is ``σ² (ΦᵀΦ)⁻¹ ≈ σ² P``; for ARMAX ``σ² P`` of the
        pseudo-linear recursion understates the spread of the ``A`` coefficients (by ~1.4x on the
        docstring's example), hence the filtered regressors. With forgetting (λ < 1), or a ``C``
        with roots on or outside the unit circle, it returns ``σ² P``: the recursion's own
        measure over its effective memory, not a parameter covariance of the whole record.
        """
        polynomials = self.polynomials_
        if self.forgetting < 1.0 or (self._nc and np.max(np.abs(np.roots(polynomials.c))) >= 1.0):
            return self.noise_variance_ * self.P_
        na, nb, nk, nc = self.na, self.nb, self.nk, self._nc
        residuals = y - polynomials.one_step_prediction(u, y)
        first = max(na, nk + nb - 1, nc)
        rows = np.arange(first, y.size)
        phi = np.column_stack([-y[rows - i] for i in range(1, na + 1)] + [u[rows - nk - j] for j in range(nb)]
                              + [residuals[rows - i] for i in range(1, nc + 1)])
        psi = scipy.signal.lfilter([1.0], polynomials.c, phi, axis=0)
        variance = float(residuals[first:] @ residuals[first:]) / max(rows.size - phi.shape[1], 1)
        scale = np.linalg.norm(psi, axis=0)  # columns in their own units (u and y may differ by decades)
        if np.any(scale == 0) or np.linalg.matrix_rank(psi / scale) < psi.shape[1]:
            raise ValueError(rank_deficiency_message(f"the regressor of the final model (na={na}, nb={nb}, nc={nc})"))
        normalised = psi / scale
        return variance * np.linalg.inv(normalised.T @ normalised) / np.outer(scale, scale)

    def _block_run(self, x0: np.ndarray, data: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        block = erls_block_function(self.na, self.nb, self.nk, self._nc, float(self.forgetting), self.backend)
        size = CHUNK * CHUNKS_PER_BLOCK
        n = data.shape[0]
        n_blocks = -(-n // size)
        padded = np.zeros((n_blocks * size, 3))  # w = 0 on the padding: state unchanged
        padded[:n] = data
        lay_p = slice(self.na + self.nb + self._nc, None)
        p = self.na + self.nb + self._nc
        errors = np.zeros(n_blocks * size)
        chunk_states = np.zeros((n_blocks * CHUNKS_PER_BLOCK, x0.size))
        buffer, evaluate = block.buffer()
        state = x0.copy()
        for k in range(n_blocks):
            d = np.ascontiguousarray(padded[k * size : (k + 1) * size])  # (size, 3) C-order == 3×size column-major
            states_out = chunk_states[k * CHUNKS_PER_BLOCK : (k + 1) * CHUNKS_PER_BLOCK]
            e_out = errors[k * size : (k + 1) * size]
            buffer.set_arg(0, memoryview(state))
            buffer.set_arg(1, memoryview(d))
            buffer.set_res(0, memoryview(states_out))
            buffer.set_res(1, memoryview(e_out))
            evaluate()
            state = states_out[-1].copy()
        n_chunks = -(-n // CHUNK)
        P_flat = chunk_states[:n_chunks, lay_p][:, : p * p]
        traces = P_flat[:, :: p + 1].sum(axis=1)
        return state, errors[:n], traces

    def _check_divergence(self, theta: np.ndarray, traces: np.ndarray) -> None:
        bad = np.flatnonzero(~np.isfinite(traces))
        if bad.size or not np.all(np.isfinite(theta)):
            where = int(bad[0]) * CHUNK if bad.size else len(traces) * CHUNK
            raise RecursionDivergedError(
                f"{type(self).__name__} diverged: covariance P is NaN/inf by sample {where} (covariance blow-up; "
                f"check the input's excitation, the forgetting factor {self.forgetting} and delta {self.delta})"
            )
        over = np.flatnonzero(traces > self.max_trace)
        if over.size:
            warnings.warn(
                f"{type(self).__name__}: covariance blow-up, trace(P) = {traces[over[0]]:.3g} > max_trace = {self.max_trace:.3g} "
                f"by sample {(int(over[0]) + 1) * CHUNK} (forgetting factor {self.forgetting} with poorly exciting input?)",
                CovarianceBlowUpWarning, stacklevel=3,
            )

    @property
    def polynomials_(self) -> Polynomials:
        """The fitted ``A, B, C`` polynomials."""
        if not hasattr(self, "theta_"):
            raise NotFittedError(f"{type(self).__name__} is not fitted yet: call fit(u, y) first")
        return Polynomials.from_theta(self.theta_, self.na, self.nb, self.nk, self._nc)

    def predict(self, u: ArrayLike, y: ArrayLike) -> np.ndarray:
        """One-step-ahead prediction with the final ``θ`` held fixed (ARMAX predictor ``C ŷ = (C − A) y + B u``)."""
        polys = self.polynomials_
        u, y = as_signal_pair(u, y)
        return polys.one_step_prediction(u, y)

    def simulate(self, u: ArrayLike, y_past: ArrayLike, u_past: ArrayLike) -> np.ndarray:
        """Free-run output (noise-free ``A y = B u``) from the measured samples just before ``u`` (oldest first)."""
        return self.polynomials_.free_run(np.asarray(u, float), np.asarray(y_past, float), np.asarray(u_past, float))


class ExtendedRecursiveLeastSquares(RecursiveLeastSquares):
    """ARMAX by extended recursive least squares (servo paper eqs. 22–25): RLS on ``φ`` extended with past residuals.

    Parameters are those of :class:`RecursiveLeastSquares` plus ``nc``, the order of ``C(z)`` (eq. 22).
    """

    def __init__(
        self, *, na: int = 2, nb: int = 1, nc: int = 1, nk: int = 1, forgetting: float = 1.0, delta: float = 1e4,
        backend: Backend = "compiled", keep_history: bool = False, max_trace: float = 1e12,
    ) -> None:
        super().__init__(na=na, nb=nb, nk=nk, forgetting=forgetting, delta=delta, backend=backend, keep_history=keep_history, max_trace=max_trace)
        self.nc = nc

    @property
    def _nc(self) -> int:
        return self.nc
