"""Torques logged with an unknown gain per joint are not read as joint zeros off the description's (h-zeros).

:mod:`estimation.identification.channel_gains` fits ``τ_j = s_j Y_j θ`` (checked against the gains a simulation
applied), and :func:`estimation.identification.joint_zeros.check_joint_zeros` names a joint's offset only when the
gains cannot explain it as well. Before, on a 6-joint PUMA whose torques were logged as currents (gains 0.3–1.8, one
joint's sign flipped, no offset), the check named a zero offset on 2 of 12 such simulated logs (63° on joint 3, 15°
on joint 2), and `oed identify` 38° on joint 2 in ``tests/test_unseen_robot_changes.py``'s case."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.signal

from benchmarks.bench_joint_zero_gains import records as logs
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.identification.channel_gains import fit_channel_gains
from estimation.identification.joint_zeros import PAIRED_ALPHA, check_joint_zeros, paired_test
from oed.fourier import random_fourier

GAINS = np.array([0.8, -0.5, 1.2, 1.8, 1.5, 0.3])


@pytest.fixture(scope="module")
def puma6():
    robot = load_robot("puma560")
    return robot, build_model(robot, "internal", "viscous,coulomb,offset")


def test_the_gains_a_simulation_applied_are_recovered(puma6):
    """Exact torques times a gain per joint (one negative): the gains relative to the first, and the torques, as
    applied; one gained channel only (the scale): the plain least-squares fit."""
    robot, model = puma6
    record = simulate(model, true_parameters(model, seed=1), random_fourier(robot, 7))
    Y = model.evaluate_base(record.q[::4], record.dq[::4], record.ddq[::4])
    tau = record.tau[::4] * GAINS
    weights = 1.0 / tau.std(axis=0)
    fitted = fit_channel_gains(Y, tau, weights, np.ones(6, dtype=bool))
    np.testing.assert_allclose(fitted.gains / fitted.gains[0], GAINS / GAINS[0], rtol=1e-5)
    np.testing.assert_allclose(fitted.predicted(Y), tau, atol=1e-6 * np.abs(tau).max())
    alone = fit_channel_gains(Y, tau, weights, np.eye(6, dtype=bool)[0])
    np.testing.assert_array_equal(alone.gains, np.ones(6))
    plain = np.linalg.lstsq((Y * weights[None, :, None]).reshape(-1, Y.shape[2]), (tau * weights).reshape(-1),
                            rcond=None)[0]
    assert alone.cost == pytest.approx(np.mean(((tau - Y @ plain) * weights) ** 2), rel=1e-6)


def test_the_paired_test_holds_its_level_and_sees_a_fall():
    """The paired test by which the gains are in question (``paired_test``) against draws whose truth is known, 1000
    of 1000 samples by 3 channels each, white and correlated in time (a first-order autoregression of 0.9): two
    residuals of the same law are called different on at most three times the level's share (measured 2.1 % and
    1.1 % at 1 %); a residual that holds another of 0.45 the noise's scale beside the same noise (20 % more MSE) is
    called larger on every white draw and on more than half of the correlated ones (measured 60 %: ten blocks of a
    record correlated over ten samples hold less evidence)."""
    generator = np.random.default_rng(7)
    weights = np.array([1.0, 2.0, 0.5])
    for rho, power in ((0.0, 1.0), (0.9, 0.5)):
        rejected, seen = 0, 0
        for _ in range(1000):
            draws = scipy.signal.lfilter([1.0], [1.0, -rho], generator.normal(size=(3, 1000, 3)), axis=1)
            rejected += paired_test(draws[0], draws[1], weights).significant
            seen += paired_test(draws[1] + 0.45 * draws[2], draws[1], weights).significant
        assert rejected <= 3 * PAIRED_ALPHA * 1000, (rho, rejected)
        assert seen >= power * 1000, (rho, seen)


@pytest.mark.slow
def test_per_joint_gains_name_no_offset_and_a_true_offset_is_found(puma6):
    """Monte Carlo over ten seeds (other parameters, motions, noise and gains each): with the torques logged with
    gains and no offset, no offset is named (at least 95 %: none of ten); with joint 2's zero 0.8 rad off and the
    torques as they are, the offset is named, within 0.1 rad, on every seed, and the torques are not said to be read
    with a gain per joint (h-gains2: the gains that stood in for the offset before it was found are tested again beside
    it; with a fixed 10 % margin they were said on 4 of these ten seeds, and 10 of 20)."""
    robot, model = puma6
    named, found = [], []
    for seed in range(10):
        (train, validate), gains = logs(model, robot, seed)
        check = check_joint_zeros(model, replace(train, tau=train.tau * gains),
                                  replace(validate, tau=validate.tau * gains), warn=False)
        if check is not None and check.marked and check.joints:
            named.append((seed, check.joints, np.rad2deg(check.offsets).round(1)))
        offsets = np.array([0.0, 0.8, 0.0, 0.0, 0.0, 0.0])
        check = check_joint_zeros(model, replace(train, q=train.q - offsets), replace(validate, q=validate.q - offsets),
                                  warn=False)
        found.append(check.marked and check.joints == (1,) and abs(check.offsets[1] - 0.8) < 0.1 and not check.gains)
    assert not named, named
    assert all(found), found


@pytest.mark.slow
def test_gains_and_a_true_offset_together(puma6):
    """The torques logged with gains (one joint's sign flipped) and joint 2's zero 0.8 rad off on the same logs: the
    scan runs with the gains the samples determine. Before (h-zeros), the scan without gains named the offset on 3 of
    these 8 seeds, one at −172°; now an offset named is the true one (within 0.1 rad, 7 of 8 seeds; the eighth says
    nothing: there the fitted model cannot tell it from the gains), and no joint is said reversed but the flipped
    torque's."""
    robot, model = puma6
    offsets = np.array([0.0, 0.8, 0.0, 0.0, 0.0, 0.0])
    found, wrong = [], []
    for seed in range(8):
        (train, validate), gains = logs(model, robot, seed)
        check = check_joint_zeros(model, replace(train, q=train.q - offsets, tau=train.tau * gains),
                                  replace(validate, q=validate.q - offsets, tau=validate.tau * gains), warn=False)
        if check is None or not check.marked:
            continue
        truly_reversed = tuple(int(joint) for joint in np.flatnonzero(gains < 0))
        if check.joints not in ((), (1,)) or (check.joints and abs(check.offsets[1] - 0.8) > 0.1) or \
                any(sign < 0 for sign in check.signs) or check.reversed_joints not in ((), truly_reversed):
            wrong.append((seed, check.joints, np.rad2deg(check.offsets).round(1), check.signs, check.torque_signs))
        found.append(check.joints == (1,))
    assert not wrong, wrong
    assert sum(found) >= 7, found


@pytest.mark.slow
@pytest.mark.parametrize("seed", [8, 16])
def test_a_reversed_torque_among_gains_is_said_on_the_seeds_the_scan_without_gains_missed(puma6, seed):
    """The torques logged with gains, one joint's sign flipped (seed 8: joint 3's, gain −0.78 beside joint 2's +1.78;
    seed 16: joint 2's, −0.95), the zeros as the description's. Before (h-gains2), the directions were scanned
    without the gains, and the scan took the neighbouring joint's torque (training cost 0.116 against 0.127 for the
    true joint on seed 8, 0.248 against 0.280 on seed 16); at that wrong joint the positive gains no longer lowered the
    held-out error, the description's bodies refused it, and nothing was said. Now, the scan having taken a reversal
    without the gains, the gains are asked again at the recorded directions, of either sign, and the directions are
    scanned with them kept positive: the true joint's torque is said reversed, with the gains, and nothing else."""
    robot, model = puma6
    (train, validate), gains = logs(model, robot, seed)
    check = check_joint_zeros(model, replace(train, tau=train.tau * gains), replace(validate, tau=validate.tau * gains),
                              warn=False)
    truly = tuple(int(joint) for joint in np.flatnonzero(gains < 0))
    assert check is not None and check.marked, check
    assert check.reversed_joints == truly and not check.joints and all(sign > 0 for sign in check.signs), check
    assert check.gains
