"""Second-order joint model (eqs. 13–14), gray-box mapping, metrics (eqs. 18–21) and the protocol."""

from __future__ import annotations

import numpy as np
import pytest

from estimation.estimators.metrics import cost_v, r2_adjusted, rmse
from estimation.servo.protocol import fit_servo_arm
from estimation.servo.model import discrete_to_gray_box, free_run, gray_box_to_discrete, joint_step_function

TABLE1 = [  # m, b, k, sigma of the paper's Table 1
    (0.294, 19.1138, 1778.9, 1801.6), (0.239, 2.4919, 114.0636, 106.5490),
    (0.144, 6.5824, 113.2759, 118.6264), (0.072, 2.3477, 41.9973, 33.7255),
]
DT = 0.01


def _aprbs_like(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.repeat(rng.uniform(-0.6, 0.6, n // 20 + 1), 20)[:n]


@pytest.mark.parametrize("m,b,k,sigma", TABLE1)
def test_gray_box_mapping_round_trips_table1(m, b, k, sigma):
    a1, a2, K = gray_box_to_discrete(b=b, k=k, sigma=sigma, mass=m, dt=DT)
    back = discrete_to_gray_box(a1, a2, K, mass=m, dt=DT)
    assert np.allclose([back.b, back.k, back.sigma], [b, k, sigma], rtol=1e-10)
    assert K / (1 + a1 + a2) == pytest.approx(sigma / k)  # static gain


def test_casadi_step_equals_eq13_written_out():
    m, b, k, sigma = TABLE1[1]
    q1, q2, u = 0.3, 0.1, 0.7
    d = 1 + k * DT**2 / m + b * DT / m
    expected = ((b * DT / m + 2) * q1 - q2 + sigma * DT**2 / m * u) / d
    assert float(joint_step_function()(q1, q2, u, b, k, sigma, m, DT)) == pytest.approx(expected, rel=1e-14)


def test_paper_eqs_27_to_29_do_not_invert_eq13_while_ours_do():
    m, b, k, sigma = TABLE1[1]
    a1, a2, K = gray_box_to_discrete(b=b, k=k, sigma=sigma, mass=m, dt=DT)
    q_n = 1.2  # the paper's formulas involve the current angle q(n)
    b_27 = ((1 - a2) * a1 + (a1 + 2) * a2) / ((a1 * DT - q_n) * a2)
    k_28 = -m / (a1 * DT**2) * (a1 + 2 + b * q_n)
    sigma_29 = m * K / DT**2 * ((1 + k * DT**2) / m + b * DT / m)
    assert abs(b_27 - b) / b > 0.5 and abs(k_28 - k) / k > 0.5 and abs(sigma_29 - sigma) / sigma > 0.5
    ours = discrete_to_gray_box(a1, a2, K, mass=m, dt=DT)
    assert ours.b == pytest.approx(b) and ours.k == pytest.approx(k) and ours.sigma == pytest.approx(sigma)


@pytest.mark.parametrize("method", ["ls", "rls", "erls"])
def test_estimators_recover_b_k_sigma_from_simulated_eq13(method):
    rng = np.random.default_rng(4)
    n = 6000
    u = np.column_stack([_aprbs_like(n, j) for j in range(4)])
    q = np.column_stack([
        free_run(gray_box_to_discrete(b=b, k=k, sigma=s, mass=m, dt=DT), u[:, j], (0.0, 0.0)) for j, (m, b, k, s) in enumerate(TABLE1)
    ]) + 1e-6 * rng.standard_normal((n, 4))
    fit = fit_servo_arm(np.arange(n) * DT, u, q, masses=tuple(r[0] for r in TABLE1), method=method, remove_mean=False)
    for joint, (_mass, b, k, s) in zip(fit.joints, TABLE1):
        assert joint.b == pytest.approx(b, rel=0.02)
        assert joint.k == pytest.approx(k, rel=0.02)
        assert joint.sigma == pytest.approx(s, rel=0.02)
        assert joint.r2_adj_free_run > 0.999


def test_free_run_r2_is_lower_than_one_step_on_noisy_data():
    rng = np.random.default_rng(5)
    m, b, k, s = TABLE1[1]
    u = _aprbs_like(5000, 9)
    q = free_run(gray_box_to_discrete(b=b, k=k, sigma=s, mass=m, dt=DT), u, (0.0, 0.0)) + 0.01 * rng.standard_normal(5000)
    fit = fit_servo_arm(np.arange(5000) * DT, u[:, None], q[:, None], masses=(m,), method="erls").joints[0]
    assert fit.r2_adj_free_run < fit.r2_adj  # one-step R² flatters
    assert fit.n_estimation == 4000 and fit.n_validation == 1000


def test_metrics_match_hand_computation():
    y, y_hat = np.array([1.0, 2.0, 3.0, 4.0, 6.0]), np.array([1.5, 2.0, 2.5, 4.0, 5.0])
    sse = 0.25 + 0 + 0.25 + 0 + 1.0
    sst = float(np.sum((y - y.mean()) ** 2))
    assert cost_v(y, y_hat) == pytest.approx(sse / 5)
    assert rmse(y, y_hat) == pytest.approx(np.sqrt(sse / 5))
    assert r2_adjusted(y, y_hat, 2) == pytest.approx(1 - (4 / 3) * sse / sst)


def test_bad_inputs_raise_named_errors():
    with pytest.raises(ValueError, match="a2"):
        discrete_to_gray_box(-1.0, 0.0, 0.1, mass=0.2, dt=DT)
    with pytest.raises(ValueError, match="mass"):
        gray_box_to_discrete(b=1, k=1, sigma=1, mass=-1, dt=DT)
    with pytest.raises(ValueError, match="parameters"):
        r2_adjusted([1.0, 2.0], [1.0, 2.0], 2)
    t = np.arange(100) * DT
    t[50] += 0.003
    with pytest.raises(ValueError, match="not uniform.*rows 49 and 50"):
        fit_servo_arm(t, np.zeros((100, 1)), np.zeros((100, 1)))
    with pytest.raises(ValueError, match="method"):
        fit_servo_arm(np.arange(100) * DT, np.zeros((100, 1)), np.zeros((100, 1)), method="gauss")


@pytest.mark.parametrize("m,b,k,sigma", TABLE1)
def test_zoh_mapping_recovers_a_sampled_continuous_plant(m, b, k, sigma):
    import scipy.signal

    num, den, _ = scipy.signal.cont2discrete(([sigma / m], [1.0, b / m, k / m]), DT, method="zoh")
    num = np.ravel(num)
    a1, a2 = den[1], den[2]
    K = float(num.sum())  # eq. 14 has one numerator coefficient: keep the static gain
    zoh = discrete_to_gray_box(a1, a2, K, mass=m, dt=DT, discretisation="zoh")
    assert np.allclose([zoh.b, zoh.k, zoh.sigma], [b, k, sigma], rtol=1e-8)
    euler = discrete_to_gray_box(a1, a2, K, mass=m, dt=DT)
    assert abs(euler.k - k) / k > 0.04  # eq. 13's inverse misreads a sampled continuous plant (k too high here)


def test_a_diverging_erls_predictor_is_named_not_a_nan_metric():
    """With forgetting 0.5 ERLS estimates C(z) with a root outside the unit circle: the one-step predictor
    (filtered by 1/C) blows up. It used to fail later as 'measured or predicted holds NaN/inf'."""
    import warnings

    from estimation.servo.protocol import fit_servo_joint

    rng = np.random.default_rng(0)
    u = _aprbs_like(6000, 0)
    a1, a2, K = gray_box_to_discrete(b=2.4919, k=114.06, sigma=106.5, mass=0.239, dt=DT)
    q = free_run((a1, a2, K), u, (0.0, 0.0), u_initial=0.0) + rng.normal(0, 0.005, u.size)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no numpy overflow warnings on the way
        with pytest.raises(ValueError, match=r"joint 2: the one-step predictor .* diverges: C\(z\) has a root of modulus"):
            fit_servo_joint(u, q, dt=DT, mass=0.239, joint=2, forgetting=0.5)


@pytest.mark.parametrize("forgetting", [0.95, 0.97])
def test_erls_noise_polynomial_outside_the_unit_circle_is_an_error_not_an_infinite_rmse(forgetting):
    """C(z) with a root just outside the unit circle: the one-step metrics used to come out as
    rmse = inf (JSON 'Infinity', exit code 0) or 1e23 — silent garbage in fit.json."""
    from estimation.servo.protocol import fit_servo_joint

    rng = np.random.default_rng(0)
    u = _aprbs_like(6000, 0)
    a1, a2, K = gray_box_to_discrete(b=2.4919, k=114.06, sigma=106.5, mass=0.239, dt=DT)
    q = free_run((a1, a2, K), u, (0.0, 0.0), u_initial=0.0) + rng.normal(0, 0.005, u.size)
    with pytest.raises(ValueError, match=r"C\(z\) has a root of modulus 1\.\d+ \(not inside the unit circle\)"):
        fit_servo_joint(u, q, dt=DT, mass=0.239, forgetting=forgetting)
    assert np.isfinite(fit_servo_joint(u, q, dt=DT, mass=0.239, forgetting=0.9).rmse)


def test_an_unstable_a_polynomial_is_an_error_even_when_the_free_run_stays_finite():
    """A(z) with a root at 1.002: over 600 samples the free run grows but stays finite, so its
    metrics used to come out as ordinary (meaningless) numbers with exit code 0."""
    from estimation.servo.protocol import fit_servo_joint

    rng = np.random.default_rng(3)
    roots = (1.002, 0.5)
    a1, a2, K = -(roots[0] + roots[1]), roots[0] * roots[1], 0.01
    u = _aprbs_like(600, 1)
    q = free_run((a1, a2, K), u, (0.0, 0.0), u_initial=0.0) + rng.normal(0, 1e-5, u.size)
    assert np.all(np.isfinite(q))
    with pytest.raises(ValueError, match=r"free-run simulation .* A\(z\) has a root of modulus 1\.00"):
        fit_servo_joint(u, q, dt=DT, mass=0.239, method="ls", remove_mean=False)
