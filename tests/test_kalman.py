"""Kalman fusion (eqs. 1–8) beats accelerometer-only angles and the integrated gyro on a simulated servo arm."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.simulation.servo_simulator import simulate_servo_arm
from dynamics.kalman import compare_fusion, kalman_fusion, kalman_step_function
from oed.aprbs_signal import APRBSDesign, design_aprbs


def test_fusion_beats_accelerometer_and_integrated_gyro():
    design = design_aprbs(APRBSDesign(duration=30.0), candidates=2, seed=11)
    record = simulate_servo_arm(design.t, design.u, seed=12)
    for j in range(4):
        scores = compare_fusion(record.gyro[:, j], record.acc_angle[:, j], record.q_true[:, j], dt=0.01, q=(1e-5, 1e-8), r=0.03**2)
        assert scores.rmse_fused < 0.6 * scores.rmse_accelerometer
        assert scores.rmse_fused < 0.5 * scores.rmse_integrated_gyro
        fused = kalman_fusion(record.gyro[:, j], record.acc_angle[:, j], dt=0.01, q=(1e-5, 1e-8), r=0.03**2)
        true_bias = record.gyro_bias[-500:, j].mean()
        assert fused.bias[-500:].mean() == pytest.approx(true_bias, abs=0.01)


def test_step_matches_the_equations_written_out():
    T, q, r = 0.01, np.array([1e-4, 1e-6]), 0.01
    x, P, omega, y = np.array([0.2, 0.05]), np.array([[0.3, 0.01], [0.01, 0.02]]), 1.5, 0.25
    A, B, C = np.array([[1, -T], [0, 1]]), np.array([T, 0]), np.array([[1.0, 0.0]])
    x_pred = A @ x + B * omega
    P_pred = A @ P @ A.T + np.diag(q)
    K = P_pred @ C.T / (C @ P_pred @ C.T + r)
    x_new = x_pred + (K * (y - C @ x_pred)).ravel()
    P_new = (np.eye(2) - K @ C) @ P_pred
    out = np.asarray(kalman_step_function()(np.concatenate((x, P.reshape(-1, order="F"))), omega, y, T, q, r)).ravel()
    assert np.allclose(out[:2], x_new, rtol=1e-13) and np.allclose(out[2:].reshape(2, 2, order="F"), P_new, rtol=1e-13)


def test_fusion_rejects_bad_input():
    with pytest.raises(ValueError, match="gyro has 3 samples but acc_angle has 2"):
        kalman_fusion(np.zeros(3), np.zeros(2), dt=0.01)
    with pytest.raises(ValueError, match="R positive"):
        kalman_fusion(np.zeros(3), np.zeros(3), dt=0.01, r=0.0)
    with pytest.raises(ValueError, match="R positive"):
        kalman_fusion(np.zeros(3), np.zeros(3), dt=0.01, r=np.nan)  # was all-NaN output
    with pytest.raises(ValueError, match="p0 .* must be positive, got -1"):
        kalman_fusion(np.zeros(3), np.zeros(3), dt=0.01, p0=-1)
    with pytest.raises(ValueError, match="x0 must be two finite numbers"):
        kalman_fusion(np.zeros(3), np.zeros(3), dt=0.01, x0=(0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="signal gyro must be one channel"):
        kalman_fusion(np.zeros((3, 2)), np.zeros(6), dt=0.01)
