"""Where the workstreams of one change meet: options of one path on the other, labels of errors that
are not against the recording, specs that rebuild a model, recorded channels kept through selections."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.effects.specs import effect_spec
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.effects.shaped import TanhCoulombFriction
from estimation.consistent.identification import identify_consistent
from estimation.identification.fit import identify
from dynamics.measurements import Measurements
from estimation.identification.trivial_predictors import trivial_mse
from oed.cli import main
from dynamics.simulation.synthetic import simulate, true_parameters


from oed.fourier import random_fourier


@pytest.fixture(scope="module")
def robot():
    return load_robot("puma560", joints=3)


def test_the_spec_of_a_shaped_law_keeps_its_variant():
    assert effect_spec(TanhCoulombFriction(joints=(0, 2))) == "coulomb:tanh@1+3"


def _averaged(n_samples: int = 40, periods: int = 3) -> Measurements:
    """Measurements of one averaged period whose recorded channels hold ``periods`` periods."""
    generator = np.random.default_rng(0)
    t = np.arange(n_samples) * 0.01
    q = generator.normal(size=(n_samples, 3))
    recorded_tau = generator.normal(size=(periods * n_samples, 3)) + 5.0
    tiled = np.tile(q, (periods, 1))
    recorded = Measurements(np.arange(periods * n_samples) * 0.01, tiled, tiled, tiled, recorded_tau)
    return Measurements(t, q, q, q, recorded_tau.reshape(periods, n_samples, 3).mean(axis=0), recorded=recorded)


def test_selecting_samples_of_an_average_keeps_their_recorded_periods():
    data = _averaged()
    kept = np.arange(40) % 4 != 0
    selected = data.select(kept)
    assert selected.recorded is not None and selected.recorded.n_samples == 3 * int(kept.sum())
    assert np.array_equal(selected.recorded.tau[: int(kept.sum())], data.recorded.tau[:40][kept])
    assert np.array_equal(selected.recorded.tau[int(kept.sum()):2 * int(kept.sum())], data.recorded.tau[40:80][kept])


def test_trivial_predictors_are_measured_against_the_recording(robot):
    data = _averaged()
    model = build_model(robot, "internal", "viscous")
    zero = trivial_mse(model, data)["zero_mse"]
    assert zero["tau1"] == pytest.approx(float(np.mean(data.recorded.tau[:, 0] ** 2)))
    assert zero["tau1"] != pytest.approx(float(np.mean(data.tau[:, 0] ** 2)))


def test_the_consistent_refit_holds_laws_with_shape_parameters_at_their_fitted_shapes(robot):
    model = build_model(robot, "internal", ("viscous", TanhCoulombFriction(joints=(0,))))
    declared = build_model(robot, "internal", "viscous")
    theta = true_parameters(declared, seed=1)
    train = simulate(declared, theta, random_fourier(robot, 2), noise={"tau1": 0.1, "tau2": 0.1, "tau3": 0.1}, seed=3)
    result = identify(model, train)
    consistent = identify_consistent(result, train, None)
    assert consistent.to_dict()["consistent"]["shape"] == {"vc1": pytest.approx(result.shapes[0].value)}
    assert np.allclose(consistent.predict(train), consistent.train.predicted)


def test_options_of_the_in_memory_path_are_refused_on_the_streamed_one(robot, tmp_path, capsys):
    declared = build_model(robot, "internal", "viscous")
    data = simulate(declared, true_parameters(declared, seed=1), random_fourier(robot, 2),
                    noise={"tau1": 0.1, "tau2": 0.1, "tau3": 0.1}, seed=3)
    path = tmp_path / "data.csv"
    data.write(path)
    out = tmp_path / "result.json"
    for option in (["--average-periods", "no"], ["--max-gap", "1"], ["--consistent"]):
        code = main(["identify", "--joints", "3", "--data", str(path), "--chunk-size", "500", "--out", str(out), *option])
        assert code == 2 and option[0] in capsys.readouterr().err
        assert not out.exists()
