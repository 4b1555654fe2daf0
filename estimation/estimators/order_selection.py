"""Order selection for ARX (batch least squares) and ARMAX (extended recursive least squares).

Each candidate ``(na, nb[, nc])`` is fitted on the estimation data and scored by an information criterion
(AIC by default) of its one-step-ahead residuals; the lowest score wins. Validation on held-out data is the
caller's job (see ``tests/test_real_daisy.py``).

Examples
--------
>>> import numpy as np
>>> from estimation.estimators.arx import ARXEstimator
>>> from estimation.estimators.order_selection import select_orders
>>> u = np.random.default_rng(0).standard_normal(3000)
>>> e = 0.1 * np.random.default_rng(1).standard_normal(3000)
>>> y = ARXEstimator.simulate_structure(a=[-1.5, 0.7], b=[1.0, 0.4], nk=1, u=u, e=e)
>>> best = select_orders(u, y, na=range(1, 5), nb=range(1, 5), criterion="bic")
>>> (best.na, best.nb)
(2, 2)
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from estimation.estimators.arx import ARXEstimator, OrderCandidate, OrderSelection, Polynomials, as_signal_pair, information_criterion
from estimation.estimators.recursive import Backend, ExtendedRecursiveLeastSquares


class OrderAtEdgeWarning(UserWarning):
    """The selected order is the largest one searched: the criterion may keep falling beyond it."""


def select_orders(
    u: ArrayLike, y: ArrayLike, *, na: Iterable[int] = range(1, 7), nb: Iterable[int] = range(1, 7), nc: Iterable[int] = (0,),
    nk: int = 1, criterion: Literal["aic", "bic", "fpe"] = "aic", require_stable: bool = True, backend: Backend = "vm",
) -> OrderSelection:
    """Fit every ``(na, nb, nc)`` (``nc = 0``: ARX by least squares; ``nc > 0``: ARMAX by ERLS) and keep the best.

    The score uses the one-step residuals of the final model over the same samples for every candidate
    (those after the longest lag), so candidates are compared on equal terms. With ``require_stable``,
    candidates whose ``A(z)`` has a root on or outside the unit circle (a free run would diverge) are skipped.
    ERLS runs on ``backend``; the default CasADi VM avoids compiling C code for every order tried.
    """
    u, y = as_signal_pair(u, y)
    na, nb, nc = list(na), list(nb), list(nc)
    for name, orders in (("na", na), ("nb", nb), ("nc", nc)):
        if not orders:
            raise ValueError(f"{name}: give at least one order to try")
    start = max(max(na), nk + max(nb) - 1, max(nc)) + 1
    candidates = []
    for c in nc:
        for a in na:
            for b in nb:
                if c == 0:
                    theta = ARXEstimator(na=a, nb=b, nk=nk).fit(u, y).theta_
                else:
                    theta = ExtendedRecursiveLeastSquares(na=a, nb=b, nc=c, nk=nk, backend=backend).fit(u, y).theta_
                if require_stable and a > 0 and np.max(np.abs(np.roots(np.concatenate(([1.0], theta[:a]))))) >= 1.0:
                    continue
                residual = y[start:] - Polynomials.from_theta(theta, a, b, nk, c).one_step_prediction(u, y)[start:]
                loss = float(np.mean(residual**2))
                candidates.append(OrderCandidate(na=a, nb=b, nc=c, score=float(information_criterion(loss, residual.size, a + b + c, criterion))))
    if not candidates:
        raise ValueError("no candidate order gave a stable A(z): widen the order ranges or set require_stable=False")
    best = min(candidates, key=lambda item: item.score)
    at_edge = [f"{name} = {value}" for name, value, orders in (("na", best.na, na), ("nb", best.nb, nb), ("nc", best.nc, nc))
               if len(orders) > 1 and value == max(orders)]
    if at_edge:
        warnings.warn(f"{criterion.upper()} picks {', '.join(at_edge)}, the largest order tried: the optimum may lie "
                      "beyond the searched range (widen it)", OrderAtEdgeWarning, stacklevel=2)
    return OrderSelection(na=best.na, nb=best.nb, nc=best.nc, criterion=criterion, candidates=tuple(candidates))
