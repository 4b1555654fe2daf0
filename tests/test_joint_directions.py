"""Joints whose recorded direction is the robot description's opposite (issue 34: encoder conventions that differ
from the URDF's): the check of the encoders' zeros names them (:func:`estimation.identification.joint_zeros.
check_joint_zeros`), and ``--joint-offsets FILE``'s ``signs`` and ``torque_signs`` declare them."""

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
from dynamics.transmission import JointDirections, TransmissionError
from dynamics.transmission_files import read_joint_directions, read_joint_offsets
from estimation.identification.joint_zeros import JointZeroWarning, check_joint_zeros
from oed.cli import main
from oed.fourier import random_fourier


@pytest.fixture(scope="module")
def puma6():
    robot = load_robot("puma560")
    model = build_model(robot, "internal", "viscous,coulomb")
    theta = true_parameters(model, seed=2)
    noise = {f"tau{j}": 0.3 for j in range(1, 7)}
    train = simulate(model, theta, random_fourier(robot, 3), noise=noise, seed=11)
    validate = simulate(model, theta, random_fourier(robot, 4), noise=noise, seed=12)
    return model, train, validate


def _logged(record, joint, kinematic=-1.0, torque=-1.0, offset=0.0):
    """The record as logged with joint ``joint``'s q, dq, ddq times ``kinematic`` and its torque times ``torque``
    (the description's q = kinematic · logged q + offset)."""
    signs, torques, offsets = np.ones(record.n_joints), np.ones(record.n_joints), np.zeros(record.n_joints)
    signs[joint], torques[joint], offsets[joint] = kinematic, torque, offset
    return replace(record, q=(record.q - offsets) * signs, dq=record.dq * signs, ddq=record.ddq * signs,
                   tau=record.tau * torques)


def test_a_reversed_axis_is_found_and_said(puma6):
    """Joint 2's q, dq, ddq and torque reversed (the URDF's axis the other way): the warning names joint 2 and the
    exact entries to declare; the held-out error falls by more than 90 %."""
    model, train, validate = puma6
    with pytest.warns(JointZeroWarning, match=r"joint 2 \(joint2\): q, dq, ddq and its torque") as caught:
        check = check_joint_zeros(model, _logged(train, 1), _logged(validate, 1))
    assert check.marked and check.reversed_joints == (1,) and check.joints == ()
    assert check.signs == (1, -1, 1, 1, 1, 1) and check.torque_signs == (1, -1, 1, 1, 1, 1)
    assert check.total_ratio < 0.1
    text = str(caught[0].message)
    assert '--joint-offsets FILE, {"signs": {"joint2": -1}, "torque_signs": {"joint2": -1}}' in text
    assert "<axis> reversed" in text


ENCODER_ALONE = (-1.0, 1.0, "q, dq and ddq (not its torque)", '{"signs": {"joint3": -1}}')
TORQUE_ALONE = (1.0, -1.0, "its torque (not q, dq, ddq)", '{"torque_signs": {"joint3": -1}}')


#: the torque reversed alone on the 6-joint arm with a validation record (about 15 s of CPU quiet: the check's gains
#: fits, 160 of them) runs in ``make test-slow``; ``make test`` keeps that question, the gains fitted on the validation
#: record and the torque alone said, on the 3-joint arm
#: (:func:`test_a_torque_reversed_alone_on_a_validation_record_is_said_after_the_gains_question`, 82 fits, about 2 s)
@pytest.mark.parametrize("held_out, kinematic, torque, said, entries", [
    ("validation", *ENCODER_ALONE), pytest.param("validation", *TORQUE_ALONE, marks=pytest.mark.slow),
    ("halves", *ENCODER_ALONE), ("halves", *TORQUE_ALONE)])
def test_an_encoder_or_a_torque_reversed_alone(puma6, kinematic, torque, said, entries, held_out):
    _assert_reversed_alone(puma6, kinematic, torque, said, entries, held_out)


def _assert_reversed_alone(arm, kinematic, torque, said, entries, held_out):
    """Joint 3's q, dq, ddq (``kinematic``) or its torque (``torque``) reversed alone on ``arm``'s records: found,
    said by name (``said``) with the entries to declare (``entries``) and no reversed ``<axis>``."""
    model, train, validate = arm
    check = check_joint_zeros(model, _logged(train, 2, kinematic, torque),
                              _logged(validate, 2, kinematic, torque) if held_out == "validation" else None, warn=False)
    assert check.marked and check.reversed_joints == (2,) and check.joints == ()
    assert check.signs[2] == kinematic and check.torque_signs[2] == torque
    text = check.message(model.robot.joint_names)
    assert f"joint 3 (joint3): {said}" in text and entries in text and "<axis>" not in text


@pytest.fixture(scope="module")
def puma3():
    """The 3-joint PUMA's records as :func:`puma6`'s (the same model, parameters' seed, motions and noise)."""
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", "viscous,coulomb")
    theta = true_parameters(model, seed=2)
    noise = {f"tau{j}": 0.3 for j in range(1, 4)}
    train = simulate(model, theta, random_fourier(robot, 3), noise=noise, seed=11)
    validate = simulate(model, theta, random_fourier(robot, 4), noise=noise, seed=12)
    return model, train, validate


def test_a_torque_reversed_alone_on_a_validation_record_is_said_after_the_gains_question(puma3, monkeypatch):
    """Joint 3's torque reversed alone, judged on a validation record: the check asks whether the torque channels
    carry gains (the gains fits, :func:`estimation.identification.channel_gains.fit_channel_gains`: 82 here, 2 on the
    halves of the training record) and still names the torque alone, as on the 6-joint arm in ``make test-slow``."""
    import estimation.identification.joint_zeros as joint_zeros

    fits = []
    fit = joint_zeros.fit_channel_gains
    monkeypatch.setattr(joint_zeros, "fit_channel_gains", lambda *args, **kwargs: fits.append(1) or fit(*args, **kwargs))
    _assert_reversed_alone(puma3, *TORQUE_ALONE, "validation")
    assert len(fits) > 2, len(fits)


def test_a_reversed_axis_with_its_zero_a_quarter_turn_off(puma6):
    """Joint 2 reversed and its zero a quarter turn off: said, and what is named predicts the validation record as
    well as the truth. Which joint: on this PUMA (joints 2 and 3 parallel) joint 3 reversed with joint 2 a quarter
    turn off fits these records as well (the scan tries a reversed joint at its logged zero only)."""
    model, train, validate = puma6
    check = check_joint_zeros(model, _logged(train, 1, offset=np.pi / 2), _logged(validate, 1, offset=np.pi / 2),
                              warn=False)
    assert check.marked and check.reversed_joints in ((1,), (2,)) and check.joints == (1,)
    assert check.total_ratio < 0.05
    assert '"offsets": {"joint2": 1.' in check.message(model.robot.joint_names)


@pytest.mark.parametrize("joint", [0, 4])
def test_a_reversal_the_parameters_take_up_is_not_said(puma6, joint):
    """Joint 1 (a vertical first axis) and joint 5 of this PUMA reversed: the base parameters take the reversal up
    (the training error is the same); nothing to warn of."""
    model, train, validate = puma6
    with warnings.catch_warnings():
        warnings.simplefilter("error", JointZeroWarning)
        check = check_joint_zeros(model, _logged(train, joint), _logged(validate, joint))
    assert not check.marked and check.reversed_joints == ()


@pytest.mark.parametrize("held_out", ["validation", "halves"])
def test_correct_directions_no_warning_and_the_scan_can_be_left_out(puma6, held_out):
    model, train, validate = puma6
    with warnings.catch_warnings():
        warnings.simplefilter("error", JointZeroWarning)
        check = check_joint_zeros(model, train, validate if held_out == "validation" else None)
    assert not check.marked and check.reversed_joints == () and check.signs == ()
    unscanned = check_joint_zeros(model, _logged(train, 1), _logged(validate, 1), warn=False, directions=False)
    assert unscanned.reversed_joints == ()


# --- --joint-offsets FILE: "signs" and "torque_signs" ---

def test_directions_read_from_json_and_csv(tmp_path):
    robot = load_robot("puma560", joints=3)
    path = tmp_path / "conventions.json"
    path.write_text(json.dumps({"signs": {"joint2": -1}, "torque_signs": [1, -1, 1], "offsets": {"3": 0.3}}))
    assert read_joint_directions(path, robot) == JointDirections((1, -1, 1), (1, -1, 1))
    assert read_joint_offsets(path, robot) == (0.0, 0.0, 0.3)
    path.write_text(json.dumps({"offsets": {"joint2": 0.1}}))
    assert read_joint_directions(path, robot) is None  # none reversed
    path.write_text(json.dumps({"joint2": 0.1}))  # the offsets object alone, as before
    assert read_joint_offsets(path, robot) == (0.0, 0.1, 0.0) and read_joint_directions(path, robot) is None
    csv = tmp_path / "conventions.csv"
    pd.DataFrame({"joint": ["joint2", "joint3"], "sign": [-1, 1], "torque_sign": [-1, -1]}).to_csv(csv, index=False)
    assert read_joint_directions(csv, robot) == JointDirections((1, -1, 1), (1, -1, -1))
    assert read_joint_offsets(csv, robot) == (0.0, 0.0, 0.0)
    # a blank cell is the joint's default, in either column: a reversed joint with no offset, an offset and no sign
    pd.DataFrame({"joint": ["joint2", "joint3"], "offset": [None, 0.5], "sign": [-1, None]}).to_csv(csv, index=False)
    assert read_joint_offsets(csv, robot) == (0.0, 0.0, 0.5)
    assert read_joint_directions(csv, robot) == JointDirections((1, -1, 1), (1, 1, 1))


@pytest.mark.parametrize("document, message", [
    ({"signs": {"joint2": 2}}, "is not a sign"),
    ({"signs": {"joint2": "minus"}}, "is not a sign"),
    ({"torque_signs": {"joint2": True}}, "is not a sign"),
    ({"signs": [1, -1]}, "2 signs for the 3 joints"),
    ({"signs": {"joint9": -1}}, "not a joint of"),
    ({"signs": "-1"}, "must be an object by joint"),
])
def test_bad_directions_name_the_file_and_the_joint(tmp_path, document, message):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(document))
    with pytest.raises(TransmissionError, match=message) as raised:
        read_joint_directions(path, load_robot("puma560", joints=3))
    assert "bad.json" in str(raised.value)


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """A 3-joint PUMA's training, validation and test records as the description has them and with joint 2's q,
    dq, ddq and torque reversed, and the file that declares it."""
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", "viscous")
    theta = true_parameters(model, seed=4)
    folder = tmp_path_factory.mktemp("directions")
    noise = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.1}
    for name, seed in (("train", 5), ("val", 6), ("test", 7)):
        simulate(model, theta, random_fourier(robot, seed), noise=noise, seed=seed + 10).write(folder / f"{name}.csv")
        frame = pd.read_csv(folder / f"{name}.csv")
        for prefix in ("q", "dq", "ddq", "tau"):
            frame[f"{prefix}2"] = -frame[f"{prefix}2"]
        frame.to_csv(folder / f"{name}_reversed.csv", index=False)
    (folder / "signs.json").write_text(json.dumps({"signs": {"joint2": -1}, "torque_signs": {"joint2": -1}}))
    return folder


def _run(folder, verb, *options, data, validate, out):
    code = main([verb, "--robot", "puma560", "--joints", "3", "--data", str(folder / data), "--validate",
                 str(folder / validate), "--friction", "viscous", "--cutoff", "20",
                 *(["--method", "ols"] if verb == "identify" else []), *options,
                 "--out", str(folder / out)])
    assert code == 0  # the defaults never exit because of the warning
    return json.loads((folder / out).read_text())


def test_the_declared_directions_give_the_description_s_result(logs):
    reference = _run(logs, "identify", data="train.csv", validate="val.csv", out="reference.json")
    declared = _run(logs, "identify", "--joint-offsets", str(logs / "signs.json"), data="train_reversed.csv",
                    validate="val_reversed.csv", out="declared.json")
    undeclared = _run(logs, "identify", data="train_reversed.csv", validate="val_reversed.csv", out="undeclared.json")
    np.testing.assert_allclose(declared["model_parameters"]["values"], reference["model_parameters"]["values"],
                               rtol=1e-6, atol=1e-8)
    for channel, value in reference["validation"]["mse"].items():
        assert declared["validation"]["mse"][channel] == pytest.approx(value, rel=1e-6)
    assert declared["model_file"]["joint_directions"] == {"signs": [1, -1, 1], "torque_signs": [1, -1, 1]}
    assert "joint_directions" not in reference["model_file"]
    # undeclared: the defaults run, predict worse, and the warning names joint 2 and the file's entries
    assert sum(undeclared["validation"]["mse"].values()) > 3 * sum(reference["validation"]["mse"].values())
    said = [message for message in undeclared["warnings"] if "look reversed" in message]
    assert len(said) == 1 and "joint 2 (joint2)" in said[0] and '"signs": {"joint2": -1}' in said[0]
    assert not any("look reversed" in message for message in declared["warnings"] + reference["warnings"])
    # oed predict applies the stored directions and writes the torques in the log's directions
    for model, data in (("reference.json", "test.csv"), ("declared.json", "test_reversed.csv")):
        assert main(["predict", "--model", str(logs / model), "--data", str(logs / data), "--out",
                     str(logs / f"predicted_{model}.csv")]) == 0
    predicted = [pd.read_csv(logs / f"predicted_{model}.csv") for model in ("reference.json", "declared.json")]
    np.testing.assert_allclose(predicted[1]["tau2"], -predicted[0]["tau2"], rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(predicted[1][["tau1", "tau3"]], predicted[0][["tau1", "tau3"]], rtol=1e-6, atol=1e-8)
    logged = pd.read_csv(logs / "test_reversed.csv")
    truth = pd.read_csv(logs / "test.csv")
    assert np.mean((logged["tau2"] - predicted[1]["tau2"]) ** 2) == pytest.approx(
        np.mean((truth["tau2"] - predicted[0]["tau2"]) ** 2), rel=1e-6)


def test_diagnose_reads_the_directions_too(logs):
    reference = _run(logs, "diagnose", data="train.csv", validate="val.csv", out="diagnosed_reference.json")
    declared = _run(logs, "diagnose", "--joint-offsets", str(logs / "signs.json"), data="train_reversed.csv",
                    validate="val_reversed.csv", out="diagnosed_declared.json")
    np.testing.assert_allclose(declared["model_file"]["theta"], reference["model_file"]["theta"], rtol=1e-6,
                               atol=1e-8)
    assert declared["model_file"]["joint_directions"]["signs"] == [1, -1, 1]


#: the torque reversed alone runs in ``make test-slow``: the check then asks whether the torque channels carry gains
#: (a reversed torque is a gain of -1), and each fit with gains is an iterative one the shared normal equations do not
#: enter (``_Problem.scored`` leaves ``normal`` unused): two whole checks of 14 s of CPU each, where the reversed axis
#: (both signs) takes 1 s. That case still scores every trial of the scan, the torques reversed alone among them, with
#: the shared normal equations, and compares them bit for bit; the torque reversed alone is still found and said in
#: ``make test`` (``test_an_encoder_or_a_torque_reversed_alone``, on a validation record and on the halves)
@pytest.mark.parametrize("kinematic, torque", [(-1.0, -1.0), pytest.param(1.0, -1.0, marks=pytest.mark.slow)])
def test_the_scan_forms_the_normal_equations_once_per_regressor_and_scores_bit_for_bit(puma6, monkeypatch,
                                                                                         kinematic, torque):
    """The direction scan forms one regressor's normal equations once for both torque signs (and once a round for
    the torques reversed alone): every score, and so the check, the same bit for bit as the fit made anew for
    each."""
    from estimation.identification import joint_zeros

    model, train, validate = puma6
    train, validate = _logged(train, 2, kinematic, torque), _logged(validate, 2, kinematic, torque)
    scored = joint_zeros._Problem.scored
    costs = {"shared": [], "anew": []}

    def recorded(which, fresh):
        def score(self, Y, signs, normal=None):
            value = scored(self, Y, signs, None if fresh else normal)
            costs[which].append(value)
            return value
        return score

    monkeypatch.setattr(joint_zeros._Problem, "scored", recorded("shared", fresh=False))
    shared = check_joint_zeros(model, train, validate, warn=False)
    monkeypatch.setattr(joint_zeros._Problem, "scored", recorded("anew", fresh=True))
    anew = check_joint_zeros(model, train, validate, warn=False)
    assert len(costs["shared"]) > 20 and costs["shared"] == costs["anew"]
    assert shared.reversed_joints == anew.reversed_joints == (2,)
    assert (shared.signs, shared.torque_signs, shared.total_ratio) == (anew.signs, anew.torque_signs, anew.total_ratio)
    Y, target = np.random.default_rng(0).normal(size=(50, 3, 4)), np.random.default_rng(1).normal(size=(50, 3))
    A = Y.reshape(-1, 4)
    scale = np.linalg.norm(A, axis=0)
    A = A / scale
    np.testing.assert_array_equal(joint_zeros._Normal(Y).solve(target),  # the formula before, inline
                                  np.linalg.lstsq(A.T @ A, A.T @ target.reshape(-1), rcond=1e-12)[0] / scale)
