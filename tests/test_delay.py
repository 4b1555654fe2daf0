"""A delay between recorded torques and the motion they answer (estimation.preprocessing.delay,
estimation.identification.delayed, the diagnosis' delay candidate, `--friction …,delay`)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.diagnosis.search import diagnose
from estimation.identification.fit import identify
from estimation.preprocessing.differentiation import FourierDifferentiation, fill_derivatives
from estimation.preprocessing.delay import DelayBounds, DelayBoundsError, delayed, split_delay
from oed.cli import main
from dynamics.simulation.synthetic import simulate, true_parameters

from oed.fourier import random_fourier

TRUE_DELAY = 0.007  # s: the torques lag the motion by 7 ms (a value unlike the default bounds)
NOISE = {"tau1": 0.1, "tau2": 0.1, "tau3": 0.05}


@pytest.fixture(scope="module")
def robot():
    return load_robot("puma560", joints=3)


@pytest.fixture(scope="module")
def records(robot):
    """Two records whose torques answer the motion 7 ms earlier: ``τ(t) = Y(motion(t − d)) θ``."""
    model = build_model(robot, "internal", "viscous")
    theta = true_parameters(model, seed=1)
    made = []
    for seed in (5, 6):
        trajectory = random_fourier(robot, seed=seed)
        data = simulate(model, theta, trajectory, rate_hz=250.0, periods=2, noise=NOISE, seed=seed)
        q, dq, ddq = trajectory.evaluate(data.t + TRUE_DELAY)  # the recorded motion runs d ahead
        made.append(dataclasses.replace(data, q=q, dq=dq, ddq=ddq))
    return model, theta, made


def test_the_motion_moves_by_the_delay(robot):
    trajectory = random_fourier(robot, seed=2)
    t = np.arange(0, 5.0, 1 / 500)
    q, dq, ddq = trajectory.evaluate(t)
    from dynamics.measurements import Measurements

    data = Measurements(t, q, dq, ddq, np.zeros_like(q))
    moved = delayed(data, 0.01)
    q_true, dq_true, _ = trajectory.evaluate(t - 0.01)
    inside = slice(5, None)  # 10 ms at 500 Hz: the first five samples come from the Taylor series of the first
    np.testing.assert_allclose(moved.q[inside], q_true[inside], atol=2e-5)
    np.testing.assert_allclose(moved.dq[inside], dq_true[inside], atol=2e-4)
    np.testing.assert_allclose(moved.q[:5], q_true[:5], atol=2e-5)
    np.testing.assert_allclose(moved.dq[:5], dq_true[:5], atol=5e-3)
    assert moved.tau is data.tau  # the channels stay as recorded


def test_identify_recovers_the_delay_and_fits_as_a_model_that_knows_it(records):
    model, theta, (train, validate) = records
    result = identify(model, train, validate, delay=DelayBounds())
    assert abs(result.delay.value - TRUE_DELAY) < 3 * result.delay.std, result.delay
    reference = identify(model, train, validate, delay=TRUE_DELAY)  # the true delay, known
    for channel, value in result.validation.mse.items():
        assert value <= 1.2 * reference.validation.mse[channel]
        assert value < 1.3 * NOISE[channel] ** 2
    document = result.to_dict()
    assert document["shape"]["delay"] == result.delay.value and document["delay"]["unit"] == "s"
    # without it, the validation error stays far above the noise
    plain = identify(model, train, validate)
    assert plain.validation.mse["tau1"] > 2 * result.validation.mse["tau1"]


@pytest.mark.parametrize("derivatives", ["given", "positions"])
def test_the_diagnosis_names_the_delay_and_nothing_else(records, derivatives):
    model, _, (train, validate) = records
    if derivatives == "positions":
        train, validate = (fill_derivatives(dataclasses.replace(data, dq=None, ddq=None),
                                            FourierDifferentiation(0.2, harmonics=5, average=False))
                           for data in (train, validate))
    diagnosis = diagnose(model, train, validate)
    assert [effect.spec for effect in diagnosis.effects] == ["delay"]
    found = diagnosis.effects[0]
    assert abs(found.shape["delay"] - TRUE_DELAY) < max(4 * found.shape_std["delay"], 5e-4)
    reference = identify(model, train, validate, delay=TRUE_DELAY)
    tolerance = 1.2 if derivatives == "given" else 1.5
    for channel, value in diagnosis.after.validation.mse.items():
        assert value <= tolerance * reference.validation.mse[channel]


def test_clean_records_get_no_delay(robot):
    model = build_model(robot, "internal", "viscous")
    theta = true_parameters(model, seed=1)
    train, validate = (simulate(model, theta, random_fourier(robot, seed=seed), rate_hz=250.0, periods=2, noise=NOISE,
                                seed=seed) for seed in (5, 6))
    diagnosis = diagnose(model, train, validate)
    assert diagnosis.effects == ()
    assert any(rejected.name == "delay" for rejected in diagnosis.rejected)


@pytest.mark.parametrize("spec, message", [
    ("viscous,delay:-1", "positive"), ("viscous,delay:abc", "seconds"), ("viscous,delay@2", "@JOINTS"),
    ("delay,delay", "twice"),
])
def test_bad_delay_specs_are_named_errors(spec, message):
    with pytest.raises(DelayBoundsError, match=message):
        split_delay(spec)


def test_reversed_bounds_are_an_error():
    with pytest.raises(DelayBoundsError, match="reversed"):
        DelayBounds(0.01, -0.01)


def test_the_cli_reports_the_delay_and_refuses_a_bad_one(records, tmp_path, capsys):
    _, _, (train, validate) = records
    train.write(tmp_path / "train.csv")
    validate.write(tmp_path / "validate.csv")
    base = ["identify", "--robot", "puma560", "--joints", "3", "--data", str(tmp_path / "train.csv"),
            "--validate", str(tmp_path / "validate.csv")]
    out = tmp_path / "result.json"
    assert main(base + ["--friction", "viscous,delay", "--out", str(out)]) == 0
    document = json.loads(out.read_text())
    assert abs(document["delay"]["value"] - TRUE_DELAY) < 3 * document["delay"]["std"]
    assert "delay" in document["shape_std"]
    bad = tmp_path / "bad.json"
    assert main(base + ["--friction", "viscous,delay:0", "--out", str(bad)]) == 2
    assert "delay" in capsys.readouterr().err and not bad.exists()


def test_a_given_delay_is_carried_by_the_result_and_its_predictions(records):
    model, _, (train, validate) = records
    result = identify(model, train, validate, delay=TRUE_DELAY)
    assert result.delay.value == TRUE_DELAY and result.delay.std == 0.0
    # predictions along the records as given move them by the delay: the validation residual is the noise
    residual = validate.tau - result.predict(validate)
    assert np.mean(residual[:, 0] ** 2) < 1.3 * NOISE["tau1"] ** 2


def test_the_motion_moves_piece_by_piece_when_time_restarts_or_rows_were_dropped(robot):
    """Two files stacked without their segment record (time restarts at 0) and rows at rest dropped
    from the first: each piece of continuous motion is moved on its own."""
    from dynamics.measurements import Measurements

    t = np.arange(0, 5.0, 1 / 500)
    parts, exact = [], []
    for seed in (7, 8):
        trajectory = random_fourier(robot, seed=seed)
        q, dq, ddq = trajectory.evaluate(t)
        keep = np.ones(t.size, dtype=bool)
        if seed == 7:
            keep[1000:1100] = False  # 0.2 s dropped
        parts.append((t[keep], q[keep], dq[keep], ddq[keep]))
        exact.append(trajectory.evaluate(t[keep] - 0.01)[0])
    data = Measurements(*(np.concatenate([part[i] for part in parts]) for i in range(4)),
                        np.zeros((sum(part[0].size for part in parts), 3)))
    moved = delayed(data, 0.01)
    np.testing.assert_allclose(moved.q, np.concatenate(exact), atol=5e-5)


def test_a_delay_never_tried_is_not_called_not_significant(records):
    model, _, (train, validate) = records
    diagnosis = diagnose(model, train, validate, candidates=())
    reason = next(rejected.reason for rejected in diagnosis.rejected if rejected.name == "delay")
    assert reason.startswith("not tested")


@pytest.mark.parametrize("value", [True, float("nan"), "5 ms"])
def test_a_given_delay_must_be_a_finite_number(records, value):
    model, _, (train, _) = records
    with pytest.raises(DelayBoundsError):
        identify(model, train, delay=value)


def test_selecting_rows_keeps_the_segments_of_a_concatenation(records):
    """Rows dropped (at rest, say) from stacked records: the segment bounds follow, so the motion is
    moved, and the HAC lags cut, at the true boundaries."""
    from estimation.data.segments import concatenate, segment_slices

    _, _, (first, second) = records
    stacked = concatenate([first, second])
    keep = np.ones(stacked.n_samples, dtype=bool)
    keep[100:300] = False
    keep[first.n_samples + 50:first.n_samples + 60] = False
    selected = stacked.select(keep)
    assert [(s.start, s.stop) for s in segment_slices(selected)] == [
        (0, first.n_samples - 200), (first.n_samples - 200, selected.n_samples)]
    assert "segments" not in stacked.select(np.arange(stacked.n_samples)[::-1]).metadata  # reordered: none kept
