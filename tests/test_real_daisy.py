"""DaISy 96-009 flexible robot arm (real data, KU Leuven DaISy via QNN): ARX/ARMAX with order selection,
validated on the held-out last quarter against naive predictors."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from estimation.estimators.arx import ARXEstimator, Polynomials
from estimation.datasets.shared import load_daisy_robot_arm
from estimation.estimators.metrics import r2_adjusted, rmse
from estimation.estimators.order_selection import OrderAtEdgeWarning, select_orders
from estimation.estimators.recursive import ExtendedRecursiveLeastSquares

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "daisy_robot_arm"
pytestmark = pytest.mark.realdata


@pytest.fixture(scope="module")
def arm():
    if not (DATA / "robot_arm.dat").is_file():
        pytest.skip(f"DaISy robot arm data not found at {DATA} (shared data folder beside the checkout)")
    return load_daisy_robot_arm(DATA)


def test_arx_with_order_selection_beats_naive_predictors_on_held_out_data(arm):
    u, y = arm.u, arm.y
    n_est = int(0.75 * y.size)
    # nearly noise-free data: AIC keeps rewarding order and stops at the edge of the search, and says so
    with pytest.warns(OrderAtEdgeWarning, match="na = 10, nb = 10, the largest order tried"):
        selection = select_orders(u[:n_est], y[:n_est], na=range(1, 11), nb=range(1, 11), criterion="aic")
    model = ARXEstimator(na=selection.na, nb=selection.nb).fit(u[:n_est], y[:n_est])
    one_step = model.predict(u, y)[n_est:]
    lag = max(selection.na, selection.nb)
    free = model.simulate(u[n_est:], y[n_est - lag : n_est], u[n_est - lag : n_est])
    held_out = y[n_est:]
    persistence = rmse(held_out, y[n_est - 1 : -1])
    print(f"\nDaISy ARX({selection.na},{selection.nb}) one-step RMSE {rmse(held_out, one_step):.3g}, "
          f"free-run RMSE {rmse(held_out, free):.3g} (R2adj {r2_adjusted(held_out, free, model.n_parameters_):.4f}), "
          f"persistence RMSE {persistence:.3g}")
    assert selection.na >= 2 and selection.nb >= 2  # a flexible arm is not first order
    assert rmse(held_out, one_step) < 0.1 * persistence
    assert rmse(held_out, free) < 0.2 * persistence
    assert r2_adjusted(held_out, free, model.n_parameters_) > 0.9


def test_armax_by_erls_with_order_selection_beats_persistence(arm):
    u, y = arm.u, arm.y
    n_est = int(0.75 * y.size)
    with warnings.catch_warnings():  # as with AIC above, BIC keeps rewarding order on these nearly noise-free data
        warnings.simplefilter("ignore", OrderAtEdgeWarning)
        selection = select_orders(u[:n_est], y[:n_est], na=range(2, 7), nb=range(2, 7), nc=(1, 2), criterion="bic")
    model = ExtendedRecursiveLeastSquares(na=selection.na, nb=selection.nb, nc=selection.nc).fit(u[:n_est], y[:n_est])
    polys = Polynomials.from_theta(model.theta_, selection.na, selection.nb, 1, selection.nc)
    assert np.max(np.abs(np.roots(polys.a))) < 1.0
    one_step = model.predict(u, y)[n_est:]
    held_out = y[n_est:]
    persistence = rmse(held_out, y[n_est - 1 : -1])
    print(f"\nDaISy ARMAX({selection.na},{selection.nb},{selection.nc}) by ERLS: one-step RMSE {rmse(held_out, one_step):.3g}, "
          f"R2adj {r2_adjusted(held_out, one_step, model.n_parameters_):.4f}; persistence RMSE {persistence:.3g}")
    assert rmse(held_out, one_step) < 0.2 * persistence
