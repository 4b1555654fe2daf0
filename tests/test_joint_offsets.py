"""Joint offsets: the encoders' zeros declared in a transmission file (``q = R⁻¹ θ_m + q₀``), loading and bad input,
and a simulated motor-side log whose zeros differ from the description's identified as well as one whose zeros agree."""

from __future__ import annotations

import json
import warnings
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from dynamics.transmission import CouplingShapeError, Transmission, TransmissionError, UnknownJointError
from dynamics.transmission_files import transmission_from_json, transmission_from_urdf
from estimation.identification.joint_zeros import JointZeroWarning, check_joint_zeros
from oed.cli import main
from oed.fourier import random_fourier
from tests.corpus.cases import CASES, OUTSIDE
from tests.corpus.records import declared_model
from tests.corpus.records import records as corpus_records
from tests.test_transmission import SIMPLE, transmission_urdf

RATIOS = [-62.6111, 107.815, -53.7063]
OFFSETS = [0.0, -np.pi / 2, 0.3]  # the joint positions where the motors' encoders read zero


def test_offsets_shift_positions_only_and_round_trip():
    matrix = np.array([[2.0, 0, 0], [0, 3.0, 0], [0, 1.5, 4.0]])
    transmission = Transmission(matrix, offsets=(0.1, -0.2, 0.0))
    q = np.random.default_rng(0).normal(size=(5, 3))
    theta = transmission.motor_positions(q)
    np.testing.assert_allclose(theta, (q - [0.1, -0.2, 0.0]) @ matrix.T)
    np.testing.assert_allclose(transmission.joint_positions(theta), q)
    np.testing.assert_allclose(transmission.motor_rates(q), q @ matrix.T)  # velocities: no offset
    np.testing.assert_allclose(transmission.joint_rates(q @ matrix.T), q)
    assert transmission.truncated(2).offsets == (0.1, -0.2)
    robot = load_robot("puma560", joints=3)
    again = transmission_from_json(transmission.to_dict(), robot)
    assert again.offsets == (0.1, -0.2, 0.0)
    assert Transmission(matrix, offsets=(0.0, 0.0, 0.0)).offsets is None  # all zero: none
    assert "offsets" not in Transmission(matrix).to_dict()


def test_offsets_from_json_by_name_number_or_list():
    robot = load_robot("puma560", joints=3)
    by_name = transmission_from_json({"ratios": RATIOS, "offsets": {"joint2": -1.5708, "3": 0.3}}, robot)
    assert by_name.offsets == (0.0, -1.5708, 0.3)
    by_list = transmission_from_json({"ratios": RATIOS, "offsets": [0, -1.5708, 0.3]}, robot)
    assert by_list.offsets == by_name.offsets
    assert transmission_from_json({"ratios": RATIOS}, robot).offsets is None


@pytest.mark.parametrize("offsets, error, message", [
    ({"joint2": "a quarter"}, TransmissionError, "is not a number"),
    ({"joint2": float("nan")}, TransmissionError, "must be finite"),
    ({"joint9": 0.1}, UnknownJointError, "not a joint of"),
    ([0.1, 0.2], CouplingShapeError, "2 offsets for the 3 joints"),
    ("0.1", TransmissionError, "must be an object by joint"),
    ({"joint2": True}, TransmissionError, "is not a number"),
])
def test_bad_offsets_name_the_problem(offsets, error, message):
    robot = load_robot("puma560", joints=3)
    with pytest.raises(error, match=message):
        transmission_from_json({"ratios": RATIOS, "offsets": offsets}, robot)


def test_offsets_of_a_urdf_transmission(tmp_path):
    element = SIMPLE.replace('<hardwareInterface>EffortJointInterface</hardwareInterface>',
                             '<hardwareInterface>EffortJointInterface</hardwareInterface><offset>0.25</offset>')
    path = transmission_urdf(tmp_path, element)
    transmission = transmission_from_urdf(path, load_robot(urdf=path))
    assert transmission.offsets == (0.25, 0.0, 0.0)
    bad = transmission_urdf(tmp_path, element.replace("0.25", "zero"))
    with pytest.raises(TransmissionError, match="<offset>"):
        transmission_from_urdf(bad, load_robot(urdf=bad))


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """A 3-joint PUMA's training and validation records, joint side and motor side with the encoders zeroed at
    ``OFFSETS`` (θ_m = R (q − q₀)), and the transmission files with and without the offsets."""
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", "viscous")
    theta = true_parameters(model, seed=4)
    folder = tmp_path_factory.mktemp("offsets")
    noise = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.1}
    declared = Transmission(np.diag(RATIOS), offsets=OFFSETS)
    for name, seed in (("train", 5), ("val", 6)):
        record = simulate(model, theta, random_fourier(robot, seed), noise=noise, seed=seed + 10)
        record.write(folder / f"{name}.csv")
        frame = pd.read_csv(folder / f"{name}.csv")
        motor = frame.drop(columns=[f"{p}{j}" for p in ("q", "dq", "ddq") for j in (1, 2, 3)])
        for prefix, values in (("qm", declared.motor_positions(record.q)), ("dqm", declared.motor_rates(record.dq)),
                               ("ddqm", declared.motor_rates(record.ddq))):
            for j, column in enumerate(values.T):
                motor[f"{prefix}{j + 1}"] = column
        motor.to_csv(folder / f"{name}_motor.csv", index=False)
    (folder / "with_offsets.json").write_text(json.dumps({"ratios": RATIOS, "offsets": {"joint2": OFFSETS[1],
                                                                                      "joint3": OFFSETS[2]}}))
    (folder / "without.json").write_text(json.dumps({"ratios": RATIOS}))
    return folder


def _identify(folder, *options, data="train.csv", validate="val.csv", out="result.json"):
    code = main(["identify", "--robot", "puma560", "--joints", "3", "--data", str(folder / data), "--validate",
                 str(folder / validate), "--friction", "viscous", "--method", "ols", "--cutoff", "20", *options,
                 "--out", str(folder / out)])
    assert code == 0
    return json.loads((folder / out).read_text())


def test_a_motor_side_log_with_declared_offsets_is_identified_as_the_joint_side_log(logs):
    joint = _identify(logs, out="joint.json", data="train.csv", validate="val.csv")
    offset = _identify(logs, "--transmission", str(logs / "with_offsets.json"), data="train_motor.csv",
                       validate="val_motor.csv", out="offset.json")
    np.testing.assert_allclose(offset["model_parameters"]["values"], joint["model_parameters"]["values"],
                               rtol=1e-6, atol=1e-8)
    assert offset["transmission"]["offsets"] == pytest.approx(OFFSETS)
    for channel, value in joint["validation"]["mse"].items():
        assert offset["validation"]["mse"][channel] == pytest.approx(value, rel=1e-6)
    # oed predict applies the stored offsets to a new motor-side log
    for model, data in (("joint.json", "val.csv"), ("offset.json", "val_motor.csv")):
        assert main(["predict", "--model", str(logs / model), "--data", str(logs / data), "--out",
                     str(logs / f"predicted_{model}.csv")]) == 0
    predicted = [pd.read_csv(logs / f"predicted_{model}.csv") for model in ("joint.json", "offset.json")]
    channels = [f"tau{j}" for j in (1, 2, 3)]
    np.testing.assert_allclose(predicted[1][channels], predicted[0][channels], rtol=1e-6, atol=1e-8)
    # the offsets not declared: the same log predicts its validation record worse, and the check says why
    undeclared = _identify(logs, "--transmission", str(logs / "without.json"), data="train_motor.csv",
                           validate="val_motor.csv", out="undeclared.json")
    total = sum(undeclared["validation"]["mse"].values())
    assert total > 1.5 * sum(joint["validation"]["mse"].values())
    warned = [message for message in undeclared["warnings"] if "offset from the robot description's zeros" in message]
    assert len(warned) == 1 and "joint 2" in warned[0] and '"offsets"' in warned[0]
    assert not any("offset from the robot" in message for message in joint["warnings"] + offset["warnings"])


# --- the check that a constant offset per joint lowers the held-out error (estimation.identification.joint_zeros) ---

@pytest.fixture(scope="module")
def puma6():
    robot = load_robot("puma560")
    model = build_model(robot, "internal", "viscous,coulomb")
    theta = true_parameters(model, seed=2)
    noise = {f"tau{j}": 0.3 for j in range(1, 7)}
    train = simulate(model, theta, random_fourier(robot, 3), noise=noise, seed=11)
    validate = simulate(model, theta, random_fourier(robot, 4), noise=noise, seed=12)
    return model, train, validate


def _recorded(record, offsets):
    """The record as logged by encoders zeroed at ``offsets`` (the description's q = the logged q + offsets)."""
    return replace(record, q=record.q - np.asarray(offsets))


def test_a_quarter_turn_off_is_found_and_said(puma6):
    model, train, validate = puma6
    offsets = [0.0, -np.pi / 2, 0.0, 0.0, 0.0, 0.0]
    with pytest.warns(JointZeroWarning, match=r"joint 2 \(joint2\) -1\.\d+ rad \(-\d+\.\d°, about a quarter turn"):
        check = check_joint_zeros(model, _recorded(train, offsets), _recorded(validate, offsets))
    assert check.marked and check.joints == (1,)
    assert check.offsets[1] == pytest.approx(-np.pi / 2, abs=0.08)
    assert check.held_out_offsets[1] == pytest.approx(-np.pi / 2, abs=0.08)
    assert check.total_ratio < 0.5


def test_without_a_validation_record_the_halves_of_the_training_record(puma6):
    """Joints 2 and 3 a quarter turn off each way (the TX40's log): on this PUMA the base parameters take up joint
    3's turn once joint 2's is right; joint 2 is named."""
    model, train, _ = puma6
    offsets = [0.0, -np.pi / 2, np.pi / 2, 0.0, 0.0, 0.0]
    with pytest.warns(JointZeroWarning, match="second half of the training record"):
        check = check_joint_zeros(model, _recorded(train, offsets))
    assert check.marked and 1 in check.joints
    assert check.offsets[1] == pytest.approx(-np.pi / 2, abs=0.25)


def test_a_calibration_offset_is_estimated(puma6):
    model, train, validate = puma6
    offsets = [0.0, 0.8, 0.0, 0.0, 0.0, 0.0]
    check = check_joint_zeros(model, _recorded(train, offsets), _recorded(validate, offsets), warn=False)
    assert check.marked and check.joints == (1,)
    assert check.offsets[1] == pytest.approx(0.8, abs=0.05)
    assert "about a quarter turn" not in check.message()


def test_the_kept_regressor_and_fit_change_nothing(puma6, monkeypatch):
    """The check's problem keeps the regressor and fit it last made (Gauss–Newton asks again for those of the step
    it accepted): the check is the same, bit for bit, as when each is made anew every time."""
    from estimation.identification import joint_zeros

    model, train, validate = puma6
    offsets = [0.0, 0.8, 0.0, 0.0, 0.0, 0.0]
    train, validate = _recorded(train, offsets), _recorded(validate, offsets)
    kept = check_joint_zeros(model, train, validate, warn=False)
    made = []

    def regressor(self, offsets):
        made.append(1)
        return self.model.evaluate_base(self.q + offsets, self.dq, self.ddq)

    def fit(self, offsets, regressor=None):
        Y = self.regressor(offsets) if regressor is None else regressor
        theta = joint_zeros._least_squares(Y * self.weights[None, :, None], self.target * self.weights)
        return theta, self.target - Y @ theta

    monkeypatch.setattr(joint_zeros._Problem, "regressor", regressor)
    monkeypatch.setattr(joint_zeros._Problem, "fit", fit)
    anew = check_joint_zeros(model, train, validate, warn=False)
    assert kept.joints == anew.joints == (1,)
    for name in ("offsets", "held_out_offsets"):
        np.testing.assert_array_equal(getattr(kept, name), getattr(anew, name))
    assert kept.mse_ratio == anew.mse_ratio and kept.total_ratio == anew.total_ratio
    assert len(made) > 0


@pytest.mark.parametrize("held_out", ["validation", "halves"])
def test_no_offset_no_warning(puma6, held_out):
    model, train, validate = puma6
    with warnings.catch_warnings():
        warnings.simplefilter("error", JointZeroWarning)
        check = check_joint_zeros(model, train, validate if held_out == "validation" else None)
    assert not check.marked and check.joints == ()


def test_an_offset_absorbed_by_the_base_parameters_is_not_said(puma6):
    """An elbow offset of this PUMA (its forearm and wrist as simulated): the first moments of the links beyond take
    it up, the prediction is unchanged; nothing to warn of. Joint 1 (a vertical axis): no column depends on it."""
    model, train, validate = puma6
    offsets = [1.0, 0.0, 0.6, 0.0, 0.0, 0.0]
    check = check_joint_zeros(model, _recorded(train, offsets), _recorded(validate, offsets), warn=False)
    assert not check.marked


@pytest.mark.parametrize("case", [case for case in CASES + OUTSIDE if case.derivatives != "positions"],
                         ids=lambda case: case.name)
def test_the_simulated_corpus_cries_no_wolf(case):
    """The corpus's records (a 3-joint PUMA with effects the declared model lacks, some outside every family): no
    offset said."""
    train, validate = corpus_records(case)
    check = check_joint_zeros(declared_model(), train, validate, warn=False)
    assert check is None or not check.marked, (check.offsets, check.total_ratio, check.mean_ratio)


def test_the_message_in_metres_for_a_prismatic_joint_and_degrees_for_a_revolute_one():
    from estimation.identification.joint_zeros import JointZeroCheck

    check = JointZeroCheck(np.array([0.02, np.pi]), (0, 1), {"tau1": 0.5, "tau2": 0.5}, 0.5, "validation record",
                           np.array([0.021, -3.1]), (True, False))
    text = check.message(("slide", "turn"))
    assert "joint 1 (slide) +0.0200 m (the validation record alone: +0.0210 m)" in text
    assert "joint 2 (turn) +3.1416 rad (+180.0°, about a half turn; the validation record alone: -177.6°)" in text
    assert '"offsets": {"slide": 0.0200, "turn": 3.1416}' in text


# --- --joint-offsets FILE: offsets added to the recorded joint positions (joint-side logs) ---

@pytest.fixture(scope="module")
def joint_side(logs):
    """The joint-side records as logged by encoders zeroed at ``OFFSETS`` (q_log = q − q₀), and the offset files."""
    for name in ("train", "val"):
        frame = pd.read_csv(logs / f"{name}.csv")
        for j, offset in enumerate(OFFSETS):
            frame[f"q{j + 1}"] -= offset
        frame.to_csv(logs / f"{name}_zeroed.csv", index=False)
    (logs / "offsets.json").write_text(json.dumps({"offsets": {"joint2": OFFSETS[1], "3": OFFSETS[2]}}))
    pd.DataFrame({"joint": ["joint2", "joint3"], "offset": OFFSETS[1:]}).to_csv(logs / "offsets.csv", index=False)
    return logs


@pytest.mark.parametrize("offsets", ["offsets.json", "offsets.csv"])
def test_joint_offsets_option_gives_the_correctly_zeroed_result(joint_side, offsets):
    folder = joint_side
    joint = _identify(folder, out="joint_ref.json")
    shifted = _identify(folder, "--joint-offsets", str(folder / offsets), data="train_zeroed.csv",
                        validate="val_zeroed.csv", out=f"shifted_{offsets}.json")
    np.testing.assert_allclose(shifted["model_parameters"]["values"], joint["model_parameters"]["values"],
                               rtol=1e-6, atol=1e-8)
    assert shifted["model_file"]["joint_offsets"] == pytest.approx(OFFSETS)
    assert "joint_offsets" not in joint["model_file"]  # outputs without the option stay as they were
    assert not any("offset from the robot" in message for message in shifted["warnings"])
    # oed predict adds the stored offsets to a new log in the encoders' zeros
    for model, data in (("joint_ref.json", "val.csv"), (f"shifted_{offsets}.json", "val_zeroed.csv")):
        assert main(["predict", "--model", str(folder / model), "--data", str(folder / data), "--out",
                     str(folder / f"predicted_{model}.csv")]) == 0
    channels = [f"tau{j}" for j in (1, 2, 3)]
    np.testing.assert_allclose(pd.read_csv(folder / f"predicted_shifted_{offsets}.json.csv")[channels],
                               pd.read_csv(folder / "predicted_joint_ref.json.csv")[channels], rtol=1e-6, atol=1e-8)


@pytest.mark.parametrize("content, name, message", [
    ('{"joint2": "a quarter"}', "bad.json", "is not a number"),
    ('{"joint9": 0.1}', "bad.json", "not a joint of"),
    ("[0.1, 0.2]", "bad.json", "2 offsets for the 3 joints"),
    ("not json", "bad.json", "not valid JSON"),
    ("joint,angle\njoint2,0.1\n", "bad.csv", "give the columns joint and offset"),
    ("joint2: 0.1", "bad.txt", "give a .json or .csv file"),
])
def test_bad_joint_offsets_files_exit_2_and_write_nothing(joint_side, capsys, content, name, message):
    folder = joint_side
    (folder / name).write_text(content)
    out = folder / "never.json"
    code = main(["identify", "--robot", "puma560", "--joints", "3", "--data", str(folder / "train.csv"), "--validate",
                 str(folder / "val.csv"), "--joint-offsets", str(folder / name), "--out", str(out)])
    assert code == 2
    error = capsys.readouterr().err
    assert error.startswith("oed identify: error:") and message in error and name in error
    assert not out.exists()


def test_joint_offsets_on_the_streamed_path(joint_side):
    """Streamed (``--chunk-size``), the records are read through joint-side copies with the zeros applied
    (:mod:`oed.workflows.joint_side`): the correctly zeroed result, the zeros in the model file."""
    folder = joint_side
    joint = _identify(folder, out="joint_ref_streamed.json")
    shifted = _identify(folder, "--joint-offsets", str(folder / "offsets.json"), "--chunk-size", "200",
                        data="train_zeroed.csv", validate="val_zeroed.csv", out="shifted_streamed.json")
    assert shifted["identification_path"] == "streamed"
    np.testing.assert_allclose(shifted["model_parameters"]["values"], joint["model_parameters"]["values"],
                               rtol=1e-6, atol=1e-8)
    assert shifted["model_file"]["joint_offsets"] == pytest.approx(OFFSETS)


def test_diagnose_reads_the_joint_offsets_too(joint_side):
    folder = joint_side
    results = []
    for data, validate, extra in (("train.csv", "val.csv", []),
                                  ("train_zeroed.csv", "val_zeroed.csv", ["--joint-offsets", str(folder / "offsets.json")])):
        out = folder / f"diagnosed_{data}.json"
        assert main(["diagnose", "--robot", "puma560", "--joints", "3", "--data", str(folder / data), "--validate",
                     str(folder / validate), *extra, "--out", str(out)]) == 0
        results.append(json.loads(out.read_text()))
    np.testing.assert_allclose(results[1]["model_file"]["theta"], results[0]["model_file"]["theta"], rtol=1e-6,
                               atol=1e-8)
    assert results[1]["model_file"]["joint_offsets"] == pytest.approx(OFFSETS)
