"""The residual tracing of joint pairs (:func:`estimation.diagnosis.candidates.coupling.traced_pairs`) against an
explicit projection.

The F statistics come from per-channel Gram matrices and Schur complements
(:mod:`estimation.diagnosis.candidates.projected_columns`); the reference here projects every column off a QR
factorisation of the whole weighted regressor, one pair at a time (the computation ``traced_pairs`` did before).
They must give the same statistics to rounding and the same pairs, on a simulated PUMA whose last motor turns with
``q5 + q6``, on pairs the declared model absorbs exactly, and on the real KUKA LWR4+ run.
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.effects.specs import build_effects
from dynamics.effects.motor import KINDS, combination_from_label, pair_combinations
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.joint_effects import PUMA560_ROTOR_INERTIA, SimulatedArmature
from dynamics.simulation.motor_effects import MotorFriction
from dynamics.simulation.sensors import NoiseModel
from dynamics.simulation.simulator import Simulator
from dynamics.simulation.synthetic import simulate, true_parameters
from dynamics.transmission import puma560_transmission
from estimation.datasets.kuka import load_kuka_run
from estimation.diagnosis.candidates.coupling import pair_tests, per_joint_extra, traced_pairs
from estimation.estimators.effect_blocks import States, effect_columns
from estimation.estimators.least_squares import stack
from oed.fourier import random_fourier
from tests.conftest import shared_data

#: the F statistics of the two computations agree to this relative tolerance (measured: 1e-12 to 3e-9 on the
#: simulated records, 9e-9 on the KUKA run, where viscous[q6+q7] keeps 1.3e-7 of its squared norm beyond the model)
TOLERANCE = 1e-7


def reference_statistics(model, train, pairs) -> list[float | None]:
    """Each pair's F statistic by explicit projection (``None``: absorbed): the columns weighted and projected
    off the QR factor of the weighted regressor, then off the per-joint columns by least squares.

    One departure from the former code: a per-joint column the declared model absorbs exactly (the armature of
    the KUKA's first joints, in the rigid-body parameters) is dropped, not fitted: projected, it is rounding
    noise (``1e-31`` of its squared norm), and least squares on two such columns fitted the residual to that
    noise (F of ``inertia[q1+q2]`` off by 1 %)."""
    problem = stack(model, train)
    Y, y, m = problem.Y.reshape(-1, problem.Y.shape[2]), problem.y.reshape(-1), model.n_channels
    theta, *_ = np.linalg.lstsq(Y, y, rcond=None)
    residual = (y - Y @ theta).reshape(-1, m)
    weight = np.tile(1.0 / np.sqrt(np.maximum(np.mean(residual**2, axis=0), 1e-300)), train.n_samples)
    Q, _ = np.linalg.qr(Y * weight[:, None])
    r0 = y * weight - Q @ (Q.T @ (y * weight))
    states = States(train.q, train.dq, train.ddq)
    statistics = []
    for pair in pairs:
        extra = per_joint_extra(model, pair)
        C = np.concatenate([effect_columns(model.kind, model.robot, effect, m, states).reshape(y.size, -1)
                            for effect in [*extra, pair]], axis=1) * weight[:, None]
        own = np.sum(C**2, axis=0)
        C = C - Q @ (Q.T @ C)
        base = C[:, :-1][:, np.sum(C[:, :-1] ** 2, axis=0) > 1e-20 * own[:-1]]
        column, r1 = C[:, -1], r0
        if base.shape[1]:
            r1 = r0 - base @ np.linalg.lstsq(base, r0, rcond=None)[0]
            column = column - base @ np.linalg.lstsq(base, column, rcond=None)[0]
        norm = float(column @ column)
        if norm <= 1e-12 * max(float(r1 @ r1), 1e-300):
            statistics.append(None)
            continue
        gain = float(column @ r1) ** 2 / norm
        dof = y.size - Y.shape[1] - len(extra) - 1
        statistics.append(gain / ((float(r1 @ r1) - gain) / dof))
    return statistics


def assert_same_tests(model, train, pairs, tolerance: float = TOLERANCE) -> list[str]:
    """Statistics and kept pairs of ``traced_pairs`` equal to the reference's; the kept pairs' names."""
    tests = pair_tests(model, train, pairs)
    reference = reference_statistics(model, train, pairs)
    assert [test.pair for test in tests] == list(pairs)
    for test, expected in zip(tests, reference):
        if expected is None:
            assert test.statistic is None, (test.pair.name, test.statistic)
        else:
            assert test.statistic == pytest.approx(expected, rel=tolerance), test.pair.name
    threshold = 1e-3 / len(pairs)
    kept = [test.pair.name for test, expected in zip(tests, reference)
            if expected is not None and test.p_value < threshold]
    assert [pair.name for pair in traced_pairs(model, train, list(pairs))] == kept
    return kept


@pytest.fixture(scope="module")
def coupled_wrist():
    """A PUMA 560 whose last motor turns with ``q5 + q6`` (motor friction and rotor inertia, torque noise)."""
    robot = load_robot("puma560")
    matrix = np.diag(puma560_transmission().ratios)
    matrix[5, 4] = matrix[5, 5]
    base = MotorFriction.default(robot)
    friction = MotorFriction(tuple(map(tuple, matrix)), base.viscous, base.coulomb, (1.0,))
    rotor = np.diag(matrix.T @ np.diag(PUMA560_ROTOR_INERTIA) @ matrix)
    simulator = Simulator(robot, (friction, SimulatedArmature(tuple(rotor))), noise=NoiseModel())
    train = simulator.run(random_fourier(robot, seed=3, frequency_hz=0.5), periods=1, warmup_periods=1,
                          with_derivatives=True, seed=3).measurements
    return robot, train


def all_pairs(n_joints: int) -> list:
    return [pair for kind in KINDS for pair in pair_combinations(n_joints, kind)]


def test_traced_pairs_match_the_explicit_projection_on_a_coupled_wrist(coupled_wrist):
    robot, train = coupled_wrist
    model = build_model(robot, "internal", "viscous,armature")
    kept = assert_same_tests(model, train, all_pairs(robot.n_joints))
    assert {"viscous[q5+q6]", "coulomb[q5+q6]"} <= set(kept), kept


@pytest.mark.parametrize("declared", ["viscous,viscous[q5-q6]", "viscous[q5-q6]"])
def test_a_pair_the_declared_model_absorbs_is_skipped(coupled_wrist, declared):
    """``viscous[q5+q6] = 2 viscous@5 + 2 viscous@6 − viscous[q5−q6]``: nothing beyond the declared model (first
    case) or beyond it and the per-joint viscous friction the test adds (second): absorbed, not tested on the
    rounding noise of its projection."""
    robot, train = coupled_wrist
    model = build_model(robot, "internal", build_effects(declared, robot))
    pairs = [pair for pair in all_pairs(robot.n_joints) if pair.name != "viscous[q5-q6]"]
    kept = assert_same_tests(model, train, pairs)
    absorbed = combination_from_label("viscous", "q5+q6", robot.n_joints)
    assert [test.statistic for test in pair_tests(model, train, [absorbed])] == [None]
    assert "viscous[q5+q6]" not in kept and "coulomb[q5+q6]" in kept, kept


@pytest.mark.parametrize("kind", ["internal", "combined"])
def test_an_absorbed_pair_is_skipped_when_the_declared_model_fits_to_the_noise(kind):
    """Torques of the declared model itself, noise 1e-6 N·m: the residual is a trillionth of a pair column's
    weighted norm, so the rounding of its projection (``eps`` of that norm from a Gram matrix) would pass the
    test's ``1e-12``-of-the-residual guard without the one relative to the column's own norm. The residual is
    1e-8 of the torques here: both computations round it at that level, and the F statistics of the pairs
    without effect (about 0.01) agree to 4e-7 only."""
    robot = load_robot("puma560")
    truth = build_model(robot, kind, build_effects("viscous,viscous[q5-q6]", robot))
    theta = true_parameters(truth, seed=0, **{"viscous[q5-q6]": 3.0})
    noise = dict.fromkeys(truth.channels, 1e-6)
    train = simulate(truth, theta, random_fourier(robot, seed=5, frequency_hz=0.5), rate_hz=500.0, noise=noise)
    pairs = [pair for pair in all_pairs(robot.n_joints) if pair.name != "viscous[q5-q6]"]
    assert_same_tests(truth, train, pairs, tolerance=1e-5)
    absorbed = combination_from_label("viscous", "q5+q6", robot.n_joints)
    assert [test.statistic for test in pair_tests(truth, train, [absorbed])] == [None]


@pytest.mark.realdata
def test_traced_pairs_match_the_explicit_projection_on_the_kuka_run():
    folder = shared_data("kuka_lwr4")
    model = build_model(load_robot(urdf=folder / "kuka_lwr4.urdf"), "internal", "viscous")
    train = load_kuka_run(folder / "kuka_lwr4_HW_measurements_1.npz")
    kept = assert_same_tests(model, train, all_pairs(7))
    assert len(kept) == 26, kept
