"""The streamed ``oed identify`` and ``oed diagnose`` (``--chunk-size``) try the log less the description's gravity
torque as memory does (h-streamload): on a log whose torques have that load subtracted (a controller's "compensated"
torques, the 6-joint PUMA of :func:`tests.test_subtracted_load.compensated_records`), both paths take the model of
such a log, write ``model_file.subtracted`` and give the same answer on the same samples.

The streamed path adds the load back to every prepared chunk of every pass (after the filter, as memory adds it to
its prepared records: :func:`estimation.streaming.chunks.loaded_chunk`); a pass that read the log as it is would
leave its figures a gravity load apart. Compared with the in-memory answer (itself checked against Pinocchio's
gravity and a plain fit in ``tests/test_subtracted_load.py``): the parameters, the validation errors, the trivial
predictors' and the paired difference of the answer and its consistent refit within :data:`SAME_ANSWER`, the same
reason word for word but its figures, and ``oed predict`` on the test record no choice saw the same errors;
``oed predict`` reproduces the streamed verb's reported validation error (relative 1e-6).

On the Fourier path of averaged periods (positions only, ``--frequency``) the load is added to the averaged period
and to the recorded samples at the fit's motion, as memory adds it to its prepared record (h-streamclock,
:func:`periodic_compensated_records`).
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.identification.subtracted_load import SubtractedLoad, subtracted_torque
from oed.cli import main
from oed.fourier import random_fourier
from tests.test_streamed_description_checks import _numbers_apart
from tests.test_subtracted_load import compensated_records

#: the largest relative difference allowed between the streamed and the in-memory figures on these records (the
#: same samples; measured: 4e-14 (identify) and 3e-11 (diagnose) for the parameters, 1e-13 and 9e-11 for the
#: validation errors)
SAME_ANSWER = 1e-6
#: the streamed reader's block (samples): the 10 s training record (2 500 samples) is read in five
CHUNK = "500"


#: the excitation frequency of :func:`periodic_compensated_records`, Hz (two whole periods a record)
PERIODIC_HZ = 0.25


def periodic_compensated_records(folder, *, compensated: bool = True, gains=None):
    """The log of :func:`tests.test_subtracted_load.compensated_records` (the 6-joint PUMA, bodies ±20 % off the
    description, the logged torque less the description's gravity torque) as a Fourier excitation of
    :data:`PERIODIC_HZ` logged without velocities: training, validation and test records of three motions, each two
    whole periods (8 s) at 250 Hz, whose periods memory and the streamed reader average (the Fourier path).
    ``compensated`` false: the torques as the model gives them (gravity in); ``gains``: each joint's logged torque
    times its gain."""
    from tests.test_unseen_robots import FRICTION, truth

    robot = load_robot("puma560", joints=6)
    model = build_model(robot, "internal", FRICTION)
    theta = truth(model)
    paths = []
    for seed in (11, 12, 13):
        t = np.arange(0.0, 2.0 / PERIODIC_HZ, 0.004)
        q, dq, ddq = random_fourier(robot, seed=seed, frequency_hz=PERIODIC_HZ).evaluate(t)
        tau = model.predict(theta, q, dq, ddq)
        if compensated:
            tau = tau - subtracted_torque(SubtractedLoad(), robot, q)
        tau = tau + np.random.default_rng(seed).normal(0.0, 1.0, tau.shape) * 0.02 * tau.std(axis=0)
        if gains is not None:
            tau = tau * np.asarray(gains, dtype=float)
        frame = pd.DataFrame({"t": t, **{f"q{j + 1}": q[:, j] for j in range(6)},
                              **{f"tau{j + 1}": tau[:, j] for j in range(6)}})
        paths.append(folder / f"periodic{seed}.csv")
        frame.to_csv(paths[-1], index=False, float_format="%.12g")
    return paths


def _run(verb: str, folder, train, validate, *options: str) -> dict:
    out = folder / f"{verb}{'-streamed' if '--chunk-size' in options else ''}.json"
    more = ["--friction", "viscous,coulomb,offset"] if verb == "identify" else []
    assert main([verb, "--data", str(train), "--validate", str(validate), *more, *options, "--out", str(out)]) == 0
    return json.loads(out.read_text())


def _predicted(document: dict, record, folder, name: str) -> dict[str, float]:
    """``oed predict``'s MSE per channel of the model file in ``document`` on ``record``."""
    model, metrics = folder / f"{name}-model.json", folder / f"{name}-metrics.json"
    model.write_text(json.dumps(document))
    assert main(["predict", "--model", str(model), "--data", str(record), "--metrics", str(metrics)]) == 0
    return json.loads(metrics.read_text())["mse"]


def _validation(document: dict, key: str) -> dict[str, float]:
    """The validation errors of the answer (``key`` ``"answer"``: identify's ``mse``, diagnose's ``chosen``) or of a
    trivial predictor."""
    validation = document["validation"]
    if key != "answer":
        return validation[key]
    return validation["chosen"]["mse"] if "chosen" in validation else validation["mse"]


def _close(measured: dict[str, float], expected: dict[str, float]) -> float:
    return max(abs(measured[channel] / expected[channel] - 1.0) for channel in expected)


@pytest.mark.slow  # each verb twice on a 6-joint arm, in memory and streamed (about 1 and 2 minutes)
@pytest.mark.parametrize("verb", ["identify", "diagnose"])
def test_the_streamed_verbs_take_the_model_of_a_compensated_log_as_memory_does(verb, tmp_path, capsys):
    train, validate, test = compensated_records(tmp_path)
    memory = _run(verb, tmp_path, train, validate)
    streamed = _run(verb, tmp_path, train, validate, "--chunk-size", CHUNK)
    capsys.readouterr()
    _same_answer(verb, memory, streamed, validate, test, tmp_path, paired=True)


@pytest.mark.slow  # each verb twice on a 6-joint arm, in memory and streamed (about 2 and 6 minutes)
@pytest.mark.parametrize("verb", ["identify", "diagnose"])
def test_the_streamed_fourier_path_takes_the_model_of_a_compensated_log_as_memory_does(verb, tmp_path, capsys):
    """The averaged periods: memory tries the log less the description's gravity torque there and takes it; the
    streamed path (h-streamclock) adds the load to the averaged period and to every recorded sample at the fit's
    motion, and gives memory's answer, parameters, validation and trivial predictors' errors, paired difference and
    test errors. Before, it said ``not_computed.subtracted`` and kept the log's torques (gravity fitted where the log
    holds none: test MSE on tau2 0.78 N²m² against memory's 0.012 for identify), and identify's paired difference was
    null on the Fourier path (its validation blocks were not scored)."""
    train, validate, test = periodic_compensated_records(tmp_path)
    memory = _run(verb, tmp_path, train, validate, "--frequency", str(PERIODIC_HZ))
    streamed = _run(verb, tmp_path, train, validate, "--frequency", str(PERIODIC_HZ), "--chunk-size", CHUNK)
    capsys.readouterr()
    assert streamed["streaming"]["files"][0]["periods_averaged"] == 2, streamed["streaming"]["files"]
    assert "gravity" not in streamed["not_computed"]  # the found gravity (none) tried too, as in memory
    _same_answer(verb, memory, streamed, validate, test, tmp_path, paired=True)


def _same_answer(verb: str, memory: dict, streamed: dict, validate, test, folder, *, paired: bool) -> None:
    """The streamed document gives memory's answer on the compensated log (the module docstring's figures);
    ``paired``: and the paired difference of the answer and its consistent refit."""
    path = "identification_path" if verb == "identify" else "diagnosis_path"
    assert memory[path] == "in-memory" and streamed[path] == "streamed"
    for document in (memory, streamed):  # both take the model of a log less the description's gravity torque
        assert document["model_file"]["subtracted"]["kind"] == "description_gravity", document["model_file"]
        assert "the description's gravity torque subtracted by the logger" in document["model_selection"]["reason"]
    assert "subtracted" not in streamed["not_computed"]  # tried, as in memory
    reasons = [document["model_selection"]["reason"] for document in (memory, streamed)]
    assert _numbers_apart(*reasons) < 1e-3, reasons
    assert streamed["model_file"]["chosen"] == memory["model_file"]["chosen"]
    if verb == "diagnose":
        assert [(effect["name"], effect["channels"]) for effect in streamed["effects"]] \
            == [(effect["name"], effect["channels"]) for effect in memory["effects"]]
        assert (streamed.get("runner_up") or {}).get("model_file", {}).get("subtracted") \
            == (memory.get("runner_up") or {}).get("model_file", {}).get("subtracted")
    theta = {name: np.asarray(document["model_file"]["theta"], dtype=float)
             for name, document in (("memory", memory), ("streamed", streamed))}
    np.testing.assert_allclose(theta["streamed"], theta["memory"], rtol=SAME_ANSWER,
                               atol=SAME_ANSWER * np.abs(theta["memory"]).max())
    # the validation errors and the trivial predictors' (on the torques the model holds: the log with the load
    # added back), as memory reports them
    for key in ("answer", "zero_mse", "nominal_mse"):
        expected, measured = (_validation(document, key) for document in (memory, streamed))
        assert _close(measured, expected) < SAME_ANSWER, key
    if paired:  # whether the validation record tells the answer from the consistent refit: from the blocks' sums
        # of the torques with the load added back (measured: 3e-11 and 2e-9 apart)
        differences = [document["model_selection"]["paired_difference"] for document in (memory, streamed)]
        assert differences[0] is not None and differences[1] is not None \
            and differences[1]["best"] == differences[0]["best"]
        for key in ("difference", "standard_error"):
            assert differences[1][key] == pytest.approx(differences[0][key], rel=SAME_ANSWER), key
    reported = streamed["model_file"]["reported"]["validation_mse"]
    assert _close(_predicted(streamed, validate, folder, "streamed-validation"), reported) < 1e-6
    # the test record no choice saw: the same errors
    errors = {name: _predicted(document, test, folder, f"{name}-test")
              for name, document in (("memory", memory), ("streamed", streamed))}
    assert _close(errors["streamed"], errors["memory"]) < SAME_ANSWER, errors
