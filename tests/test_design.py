"""Excitation design (PUMA paper, IV.A): derivatives, bounds at 1 kHz, optimality, JSON round trip."""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor

import casadi
import numpy as np
import pytest

from dynamics.robots import load_robot
from oed.bounds import PUMA_BOUNDS
from oed.excitation import DesignSettings, ExcitationDesign, design_excitation
from oed.fourier import FourierTrajectory


@pytest.fixture(scope="module")
def puma():
    return load_robot("puma560", joints=3)


@pytest.fixture(scope="module")
def problem(puma):
    return ExcitationDesign(puma, "internal", PUMA_BOUNDS)


@pytest.fixture(scope="module")
def result(problem):
    return design_excitation(problem.robot, starts=2, seed=3, problem=problem)


def test_objective_gradient_matches_central_differences(problem):
    x0 = problem.random_start(np.random.default_rng(0))
    x = casadi.MX.sym("x", problem.n_variables)
    objective = problem.cost_function()
    gradient = np.asarray(casadi.Function("g", [x], [casadi.gradient(objective(x), x)])(x0)).reshape(-1)
    step = 1e-6
    numeric = np.array([
        (float(objective(x0 + step * e)) - float(objective(x0 - step * e))) / (2 * step)
        for e in np.eye(problem.n_variables)
    ])
    np.testing.assert_allclose(gradient, numeric, rtol=1e-5, atol=1e-6)


def test_objective_is_the_criterion_of_the_sampled_regressor(problem):
    """The CasADi graph (linear maps + mapped regressor) equals −log det of numpy-sampled Y_b / N."""
    x0 = problem.random_start(np.random.default_rng(1))
    s = problem.settings
    trajectory = problem.trajectory(x0)
    t = np.arange(s.cost_samples) / s.cost_samples / s.frequency_hz
    M = problem.information(*trajectory.evaluate(t)) / s.cost_samples
    assert float(problem.cost_function()(x0)) == pytest.approx(-np.linalg.slogdet(M)[1], rel=1e-9)


def test_constraint_rows_reproduce_the_trajectory(problem):
    x0 = problem.random_start(np.random.default_rng(2))
    t = np.linspace(0, 5, 17)
    A, _, _ = problem.constraint_matrix(t)
    q, dq, ddq = problem.trajectory(x0).evaluate(t)
    expected = np.concatenate([np.concatenate([q[:, j], dq[:, j], ddq[:, j]]) for j in range(3)])
    np.testing.assert_allclose(A @ x0, expected, atol=1e-12)


def test_random_starts_meet_the_bounds_at_1khz(problem):
    generator = np.random.default_rng(4)
    for _ in range(5):
        _, q, dq, ddq = problem.sample(problem.random_start(generator))
        assert PUMA_BOUNDS.violations(q, dq, ddq, tolerance=0) == []


def test_design_meets_the_bounds_on_the_full_1khz_grid(result):
    t, q, dq, ddq = result.trajectory.sample(1000.0)
    assert t.size == 5000
    assert PUMA_BOUNDS.violations(q, dq, ddq, tolerance=0) == []


def test_design_beats_20_random_feasible_trajectories(problem, result):
    generator = np.random.default_rng(11)
    random_costs = [problem.evaluate(problem.random_start(generator))["cost"] for _ in range(20)]
    assert result.cost < min(random_costs)
    assert all(start.cost <= start_cost for start, start_cost in
               zip(result.starts, [problem.evaluate(s.x0)["cost"] for s in result.starts]))


def test_reported_cost_is_unscaled_logdet_over_5000_samples(problem, result):
    _, q, dq, ddq = result.trajectory.sample(1000.0)
    Y = problem.identification_model.evaluate_base(q, dq, ddq).reshape(-1, problem.identification_model.n_base)
    assert result.cost == pytest.approx(-np.linalg.slogdet(Y.T @ Y)[1], rel=1e-10)
    assert result.cond == pytest.approx(np.linalg.cond(Y), rel=1e-6)
    assert result.trajectory.metadata["cost"] == result.cost


def test_result_records_every_start(result):
    assert len(result.starts) == 2
    assert {start.index for start in result.starts} == {0, 1}
    assert all(start.iterations > 0 and start.time_s > 0 for start in result.starts)
    assert result.cost == min(start.cost for start in result.starts if start.success)


@pytest.mark.parametrize("pool", [ProcessPoolExecutor, ThreadPoolExecutor])
def test_executor_gives_the_serial_result(problem, result, pool):
    """Starts submitted to a process pool (as ``oed design --workers``) or to threads (as on a dask
    worker) reproduce the serial run (threads each build their own problem and solver)."""
    with pool(2) as executor:
        pooled = design_excitation(problem.robot, starts=2, seed=3, problem=problem, executor=executor)
    assert [start.index for start in pooled.starts] == [0, 1]
    for serial_start, pooled_start in zip(result.starts, pooled.starts):
        np.testing.assert_allclose(pooled_start.x0, serial_start.x0, rtol=0, atol=0)
        np.testing.assert_allclose(pooled_start.x, serial_start.x, rtol=1e-9, atol=1e-12)
        assert pooled_start.status == serial_start.status
    assert pooled.best == result.best
    assert pooled.cost == pytest.approx(result.cost, rel=1e-12)


def test_json_round_trip_keeps_coefficients_and_metadata(result, tmp_path):
    path = tmp_path / "traj.json"
    result.trajectory.save(path)
    loaded = FourierTrajectory.load(path)
    for key in ("q0", "a", "b"):
        np.testing.assert_array_equal(getattr(loaded, key), getattr(result.trajectory, key))
    for key in ("model", "criterion", "cost", "cond", "bounds", "solver"):
        assert loaded.metadata[key] == result.trajectory.metadata[key]
    np.testing.assert_allclose(loaded.sample(1000.0)[1], result.trajectory.sample(1000.0)[1])


def test_250_cost_samples_give_the_5000_sample_objective(puma):
    """The sample-normalised objective at 250 samples matches 5 000 samples (same optimum)."""
    coarse = ExcitationDesign(puma, "combined", settings=DesignSettings(cost_samples=250))
    fine = ExcitationDesign(puma, "combined", settings=DesignSettings(cost_samples=5000))
    generator = np.random.default_rng(5)
    for _ in range(3):
        x0 = coarse.random_start(generator)
        assert float(coarse.cost_function()(x0)) == pytest.approx(float(fine.cost_function()(x0)), abs=1e-3)


def test_ctrl_c_during_a_solve_ends_the_design_instead_of_one_start():
    """CasADi turns SIGINT into the IPOPT status NonIpopt_Exception_Thrown; the design went on with
    the next starts and wrote its result."""
    import os
    import signal

    # IPOPT alone (no SQP hand-over after 20 iterations, which begins about 0.2 s into a start here and made the
    # signal land on either side of it): the whole solve, ~0.65 s, is IPOPT's
    problem = ExcitationDesign(load_robot("puma560", joints=3), "combined",
                               settings=DesignSettings(cost_samples=3000, sqp_after=None))
    problem.build()
    x0 = problem.random_start(np.random.default_rng(0))
    problem.solve(x0)  # the first solve sets up the derivatives: keep it out of the timed one
    previous = signal.signal(signal.SIGALRM, lambda *_: os.kill(os.getpid(), signal.SIGINT))
    signal.setitimer(signal.ITIMER_REAL, 0.2)  # inside IPOPT
    try:
        with pytest.raises(KeyboardInterrupt, match="interrupted during an IPOPT solve"):
            problem.solve(x0)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def test_a_trajectory_scaled_onto_the_bounds_is_reported_not_passed_off_as_optimal():
    """With no margin on a coarse grid and no refinement rounds the 1 kHz check fails and the
    oscillation is scaled down: the start says so and the design warns."""
    from oed.excitation import ShrunkDesignWarning

    class NoMargin(ExcitationDesign):
        grid_factor = property(lambda self: 1.0)

    problem = NoMargin(load_robot("puma560", joints=3), "internal",
                       settings=DesignSettings(constraint_points=20, refinements=0))
    with pytest.warns(ShrunkDesignWarning, match="scaled down onto them"):
        result = design_excitation(problem.robot, problem=problem, starts=1)
    assert result.trajectory.metadata["solver"]["per_start"][0]["shrunk"] is True


def test_ipopt_options_reach_the_solver_and_are_checked():
    settings = DesignSettings(ipopt_options=(("max_iter", 1),))  # over the settings' own max_iter
    problem = ExcitationDesign(load_robot("puma560", joints=3), "internal", settings=settings)
    assert problem.solve(problem.random_start(np.random.default_rng(0))).status == "Maximum_Iterations_Exceeded"
    with pytest.raises(ValueError, match="ipopt_options must be .name, value. pairs"):
        DesignSettings(ipopt_options=(("max_iter",),))
