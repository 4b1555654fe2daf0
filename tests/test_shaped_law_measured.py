"""A shaped friction law stands over the plain law of its joint only when the validation record measures its gain
(``estimation.diagnosis.plain_laws.measured_gain``: more than ``TIED_SE`` standard errors of the difference, from
``BLOCKS`` contiguous blocks); the servo arm of ``tests/test_unseen_robots.py`` (slow) is the end-to-end case."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from estimation.diagnosis.plain_laws import measured_gain
from estimation.identification.validation import Comparison


def _result(residuals: np.ndarray) -> SimpleNamespace:
    n = residuals.shape[0]
    return SimpleNamespace(validation=Comparison(np.arange(n) * 0.01, residuals, np.zeros_like(residuals),
                                                 ("tau1", "tau2")))


def test_a_gain_within_the_noise_of_the_validation_record_is_not_measured():
    rng = np.random.default_rng(0)
    noise = rng.normal(size=(400, 2))
    plain = _result(noise)
    tied = _result(noise * np.array([0.995, 1.0]) + 0.05 * rng.normal(size=(400, 2)))  # 0.5 % lower on tau1: noise
    clear = _result(noise * np.array([0.5, 1.0]))  # a quarter of the squared error on tau1
    assert not measured_gain(tied, plain, 0)
    assert measured_gain(clear, plain, 0)
    assert not measured_gain(plain, clear, 0)
    assert measured_gain(clear, plain)  # the score (geometric mean over the channels)
    assert not measured_gain(tied, plain)
    # errors without their samples (sums): the lower one is taken as measured
    summed = SimpleNamespace(validation=SimpleNamespace(mse={"tau1": 0.9, "tau2": 1.0}, channels=("tau1", "tau2")))
    assert measured_gain(summed, plain, 0) == (0.9 < plain.validation.mse["tau1"])


def test_the_score_on_some_channels_reads_those_channels_only():
    rng = np.random.default_rng(1)
    noise = rng.normal(size=(400, 2))
    plain = _result(noise)
    clear = _result(noise * np.array([0.5, 1.0]))  # lower on tau1 only
    assert measured_gain(clear, plain, rows=[0])
    assert not measured_gain(clear, plain, rows=[1])


def _records(law, theta_of):
    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from dynamics.simulation.synthetic import simulate
    from oed.fourier import random_fourier

    robot = load_robot("puma560", joints=3)
    declared = build_model(robot, "internal", "viscous")
    truth = build_model(robot, "internal", (*declared.effects, *law))
    theta = theta_of(truth)
    noise = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.1}
    return declared, {name: simulate(truth, theta, random_fourier(robot, seed=seed), rate_hz=100.0, periods=1,
                                     noise=noise, seed=seed) for name, seed in (("train", 5), ("other", 6))}


def test_a_sigmoid_fitted_to_the_sign_law_gives_way_to_the_plain_law():
    """Joint 2's truth is the sign law (Coulomb friction and an offset); a ``sigmoid`` fitted there validates within
    the noise of the plain law: its shape is not measured, and the plain law takes the joint (the 1 % screen alone
    kept the sigmoid)."""
    from dynamics.effects.linear import CoulombFriction, JointOffset
    from dynamics.effects.shaped import SigmoidFriction
    from dynamics.models import build_model
    from dynamics.simulation.synthetic import true_parameters
    from estimation.diagnosis.plain_laws import plain_law_choice
    from estimation.identification.fit import identify

    declared, made = _records((CoulombFriction(joints=(1,)), JointOffset(joints=(1,))),
                              lambda truth: true_parameters(truth, seed=1, coulomb=[3.0], offset=[0.8]))
    law = SigmoidFriction(joints=(1,))
    after = identify(build_model(declared.robot, "internal", declared.effects + (law,)), made["train"], made["other"])
    choice = plain_law_choice(declared, after, [law], made["train"], made["other"], min_improvement=0.01,
                              threshold=1e-3 / 50)
    assert choice is not None and choice.adopted
    assert [effect for effect, _ in choice.dropped] == [law]
    assert {effect.name for effect in choice.plain} <= {"coulomb", "offset"} and "coulomb" in \
        {effect.name for effect in choice.plain}
    assert "gain not measured" in choice.dropped[0][1]


def test_a_smooth_coulomb_law_whose_shape_the_validation_measures_is_kept():
    """Joint 2's truth is a smooth Coulomb law (``3 tanh(q̇₂/0.3)``): the diagnosed ``coulomb:tanh`` validates
    measurably better than the plain law there, and stays."""
    from dataclasses import replace

    from dynamics.effects.shaped import TanhCoulombFriction
    from dynamics.models import build_model
    from dynamics.simulation.synthetic import true_parameters
    from estimation.diagnosis.plain_laws import plain_law_choice
    from estimation.identification.fit import identify

    declared, made = _records((), lambda truth: true_parameters(truth, seed=1))
    for name, record in made.items():
        tau = record.tau.copy()
        tau[:, 1] += 3.0 * np.tanh(record.dq[:, 1] / 0.3)
        made[name] = replace(record, tau=tau)
    law = TanhCoulombFriction(joints=(1,))
    after = identify(build_model(declared.robot, "internal", declared.effects + (law,)), made["train"], made["other"])
    assert plain_law_choice(declared, after, [law], made["train"], made["other"], min_improvement=0.01,
                            threshold=1e-3 / 50) is None
