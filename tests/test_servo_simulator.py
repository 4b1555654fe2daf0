"""Servo-arm simulator: steady state, saturation, gravity load, bad input named."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.simulation.servo_simulator import PAPER_JOINTS, simulate_servo_arm


def _step(n: int, start, end) -> np.ndarray:
    u = np.tile(np.asarray(start, float), (n, 1))
    u[n // 4 :] = end
    return u


def test_steady_state_is_sigma_over_k_without_gravity_and_speed_is_limited():
    n = 400
    u = _step(n, [0.0, 1.0, 1.5, 1.0], [1.0, 1.9, 3.0, 4.0])
    record = simulate_servo_arm(np.arange(n) * 0.01, u, gravity=False, seed=0)
    gains = np.array([j.sigma / j.k for j in PAPER_JOINTS])
    assert np.allclose(record.q_true[-1], gains * u[-1], atol=1e-3)
    assert np.abs(record.dq_true).max() <= 5.2 * 1.3  # slew limited to about the rated speed
    assert record.q.shape == record.gyro.shape == record.acc_angle.shape == (n, 4)


def test_gravity_load_shifts_the_pitch_joints_only():
    n = 300
    u = np.tile([0.0, 0.8, 1.5, 1.0], (n, 1))
    with_g = simulate_servo_arm(np.arange(n) * 0.01, u, gravity=True, seed=0).q_true[-1]
    without = simulate_servo_arm(np.arange(n) * 0.01, u, gravity=False, seed=0).q_true[-1]
    shift = with_g - without
    assert abs(shift[0]) < 1e-9 and np.all(np.abs(shift[1:3]) > 1e-4)


def test_command_outside_joint_range_is_named():
    u = np.tile([0.0, 1.0, 1.5, 1.0], (50, 1))
    u[10, 2] = 3.5
    with pytest.raises(ValueError, match=r"column u3 = 3.5 rad at row 10 is above the upper joint-3 bound 3.142"):
        simulate_servo_arm(np.arange(50) * 0.01, u)


def test_non_uniform_time_is_named():
    t = np.arange(50) * 0.01
    t[20:] += 0.004
    with pytest.raises(ValueError, match="not uniform"):
        simulate_servo_arm(t, np.tile([0.0, 1.0, 1.5, 1.0], (50, 1)))


def test_end_to_end_linear_regime_recovers_table1_with_zoh_mapping():
    from estimation.servo.protocol import fit_servo_arm
    from oed.aprbs_signal import APRBSDesign, design_aprbs

    design = design_aprbs(APRBSDesign(duration=60.0), seed=1)
    record = simulate_servo_arm(design.t, design.u, max_speed=1e3, gravity=False, seed=2)  # no saturation: linear
    fit = fit_servo_arm(design.t, design.u, record.q, masses=tuple(j.mass for j in PAPER_JOINTS), discretisation="zoh")
    for joint, truth in zip(fit.joints, PAPER_JOINTS):
        assert joint.k == pytest.approx(truth.k, rel=0.10)
        assert joint.sigma == pytest.approx(truth.sigma, rel=0.10)
        assert joint.b == pytest.approx(truth.b, rel=0.25)
        assert joint.r2_adj_free_run > 0.99
