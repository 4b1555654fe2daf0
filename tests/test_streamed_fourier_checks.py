"""The joint-zero, mount and friction-drift checks on the streamed Fourier path, as memory makes them.

Memory checks the joints' zeros, gravity's direction and the friction on the validation record against the training
record's on its prepared records whatever the derivatives: on the Fourier path a file's averaged period, or its
every sample with the fit's motion where its periods are not averaged (a jittered log's grid). The streamed verbs
(``--chunk-size``) ran none of them there (``not_computed.friction_drift``: "not checked on averaged periods"), so
on the jittered log of :mod:`tests.test_streamed_every_sample_fourier` memory said joint 2 looks offset by +14.3° and
the streamed path said nothing. Now the checks' pass reads the same prepared samples
(:func:`estimation.streaming.periods.plan_chunks`, the counts of :func:`estimation.streaming.description_checks.
prepared_count`) and says what memory says.
"""

from __future__ import annotations

import json

import pytest

from tests.test_streamed_every_sample_fourier import records, robot  # noqa: F401  (fixtures)

ZERO_WARNING = "look offset from the robot description's zeros"


def _run(main, verb: str, train, validate, out, *options: str) -> dict:
    friction = ("--friction", "viscous") if verb == "diagnose" else ()
    assert main([verb, "--robot", "puma560", "--joints", "3", *friction, "--data", str(train), "--validate",
                 str(validate), "--out", str(out), "--quiet", *options]) == 0
    return json.loads(out.read_text())


def warnings_of(document: dict) -> list[str]:
    """The warnings of a result document: ``oed identify``'s list, ``oed diagnose``'s by model."""
    said = document["warnings"]
    return list(said) if isinstance(said, list) else [text for texts in said.values() for text in texts or ()]


@pytest.mark.slow  # two verbs in memory and streamed on two logs: about 80 s
@pytest.mark.parametrize(("verb", "train"), [("diagnose", "train"), ("identify", "regular")])
def test_the_streamed_fourier_path_checks_as_memory(records, tmp_path, capsys, verb, train):  # noqa: F811
    """``diagnose`` on the jittered log (every sample fitted) and ``identify`` on the regular one (periods
    averaged): the streamed path says memory's joint zero (joint 2, +14.3° / +14.5°) word for word, fills
    ``friction_drift`` with memory's figures (relative 1e-6; measured 1e-10) and no longer names it in
    ``not_computed``; the mount marks on neither. On main the streamed document held ``friction_drift: null``
    and no joint-zero warning. The diagnosis's runner-up (a ripple in place of the offset on tau1) is fitted along
    the motion moved by the chosen delay on both paths; its model file now holds that delay streamed too, and its
    training errors against the recording are memory's (relative 1e-6; main: 0.049 against 0.017 on tau1)."""
    from oed.cli import main

    documents = {name: _run(main, verb, records[train], records["validate"], tmp_path / f"{name}.json", *options)
                 for name, options in (("memory", ()), ("streamed", ("--chunk-size", "128")))}
    capsys.readouterr()
    memory, streamed = documents["memory"], documents["streamed"]
    assert streamed["preprocessing"]["method"] == memory["preprocessing"]["method"] == "fourier"
    averaged = streamed["streaming"]["files"][0]["periods_averaged"]
    assert averaged == (2 if train == "regular" else 0)
    said = [[text for text in warnings_of(document) if ZERO_WARNING in text] for document in (memory, streamed)]
    assert len(said[0]) == 1 and "joint 2 (joint2) +0.2" in said[0][0] and "(+14." in said[0][0]
    assert said[1] == said[0]
    assert not any("gravity" in text and "mount" in text for text in warnings_of(streamed))
    assert "friction_drift" not in streamed["not_computed"]
    drift = memory["friction_drift"]
    assert {key: value for key, value in streamed["friction_drift"].items() if key != "joints"} \
        == {key: value for key, value in drift.items() if key != "joints"}  # the method and its limits
    assert streamed["friction_drift"]["joints"].keys() == drift["joints"].keys()
    for name, joint in drift["joints"].items():
        for key, value in joint.items():
            if isinstance(value, float):
                assert streamed["friction_drift"]["joints"][name][key] == pytest.approx(value, rel=1e-6, abs=1e-12)
            else:
                assert streamed["friction_drift"]["joints"][name][key] == value
    if verb == "diagnose":
        rival, expected = streamed["runner_up"], memory["runner_up"]
        assert rival["spec"] == expected["spec"] and expected["model_file"]["delay"] is not None
        assert rival["model_file"]["delay"]["value"] == pytest.approx(expected["model_file"]["delay"]["value"],
                                                                     rel=1e-6)
        for record in ("train", "validation"):
            assert rival[record]["mse"] == pytest.approx(expected[record]["mse"], rel=1e-6)
        assert rival["model_file"]["theta"] == pytest.approx(expected["model_file"]["theta"], rel=1e-6, abs=1e-9)


@pytest.fixture(scope="module")
def tails(robot, tmp_path_factory):  # noqa: F811
    """Training and validation logs of two and a half periods (3125 samples at 250 Hz, 0.2 Hz), as
    ``records`` simulates them: their two whole periods averaged, the half period past them scored as recorded."""
    import dataclasses

    from dynamics.effects.linear import JointOffset
    from dynamics.models import build_model
    from dynamics.simulation.synthetic import simulate, true_parameters
    from oed.fourier import random_fourier
    from tests.test_streamed_every_sample_fourier import NOISE, TRUE_DELAY

    folder = tmp_path_factory.mktemp("fourier_tails")
    truth = build_model(robot, "internal", ("viscous", JointOffset(joints=(0,))))
    theta = true_parameters(truth, seed=1, offset=[2.0])
    paths = {}
    for name, seed in (("train", 5), ("validate", 6)):
        trajectory = random_fourier(robot, seed=seed)
        data = simulate(truth, theta, trajectory, rate_hz=250.0, periods=3, noise=NOISE, seed=seed + 10)
        q, dq, ddq = trajectory.evaluate(data.t + TRUE_DELAY)
        frame = dataclasses.replace(data, q=q, dq=dq, ddq=ddq).to_frame()
        paths[name] = folder / f"{name}.csv"
        frame[[column for column in frame.columns if not column.startswith(("dq", "ddq"))]].iloc[:3125].to_csv(
            paths[name], index=False, float_format="%.17g")
    return paths


@pytest.mark.slow  # a diagnosis in memory and streamed, two predictions: about 40 s a case
@pytest.mark.parametrize("case", ["no", "yes on one period", "a tail past the whole periods"])
def test_the_streamed_fourier_path_averages_as_memory(records, tails, tmp_path, capsys, case):  # noqa: F811
    """``--average-periods no`` was refused streamed (exit 2); ``yes`` on a file of one whole period and a half
    averaged the one period in memory and fitted every sample streamed (validation tau2 0.010397 N²m² in memory,
    0.010288 streamed); a file of two whole periods and a half was scored streamed on its whole periods only where
    memory scores every recorded sample, the tail too (validation 1.3 % apart on tau3, training 0.8 %). Now each
    gives memory's answer: effects, chosen model, parameters, validation, training and runner-up errors (relative
    1e-6; measured 1e-9), and ``oed predict`` reproduces the streamed verb's validation error."""
    from oed.cli import main

    if case == "no":
        train, validate, options, averaged = records["regular"], records["validate"], ("--average-periods", "no"), 0
    elif case == "yes on one period":
        lines = records["regular"].read_text().splitlines()
        train = tmp_path / "one_period_and_a_half.csv"
        train.write_text("\n".join(lines[:1 + 1875]) + "\n")  # the header and 1.5 periods of 1250 samples
        validate, options, averaged = records["validate"], ("--average-periods", "yes"), 1
    else:
        train, validate, options, averaged = tails["train"], tails["validate"], (), 2
    options = ("--frequency", "0.2", *options)
    documents = {name: _run(main, "diagnose", train, validate, tmp_path / f"{name}.json", *options, *more)
                 for name, more in (("memory", ()), ("streamed", ("--chunk-size", "128")))}
    capsys.readouterr()
    memory, streamed = documents["memory"], documents["streamed"]
    assert streamed["diagnosis_path"] == "streamed"
    assert streamed["streaming"]["files"][0]["periods_averaged"] == averaged
    assert [effect["spec"] for effect in streamed["effects"]] == [effect["spec"] for effect in memory["effects"]]
    assert streamed["model_selection"]["chosen"] == memory["model_selection"]["chosen"]
    assert streamed["model_file"]["theta"] == pytest.approx(memory["model_file"]["theta"], rel=1e-6, abs=1e-9)
    for which in ("after", "chosen"):
        assert streamed["validation"][which]["mse"] == pytest.approx(memory["validation"][which]["mse"], rel=1e-6)
        assert streamed["train"][which]["mse"] == pytest.approx(memory["train"][which]["mse"], rel=1e-6)
    assert streamed["runner_up"]["train"]["mse"] == pytest.approx(memory["runner_up"]["train"]["mse"], rel=1e-6)
    metrics = tmp_path / "metrics.json"
    assert main(["predict", "--model", str(tmp_path / "streamed.json"), "--data", str(validate), "--metrics",
                 str(metrics)]) == 0
    capsys.readouterr()
    assert json.loads(metrics.read_text())["mse"] == pytest.approx(streamed["validation"]["chosen"]["mse"], rel=1e-6)
