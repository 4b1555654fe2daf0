"""A URDF that branches or holds ``<mimic>`` joints (a gripper at the flange) read on the defaults as the chain the
log's joint columns determine (issue 34: no verb exits on its defaults where ``--joint-names`` would have worked)."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dynamics.errors import RobotDescriptionError
from dynamics.robots import load_robot
from dynamics.urdf import logged_chain
from tests.test_unseen_robot_kinds import quiet
from tests.test_unseen_robot_labs import write_records
from tests.test_unseen_robot_logs import gripper, lab

ARM = ("joint1", "joint2", "joint3")
FINGERS = ("finger_left_joint", "finger_right_joint")


@pytest.fixture(scope="module")
def records(tmp_path_factory) -> tuple[Path, dict]:
    """The PUMA's first 3 joints as a URDF and its training, validation and test records (3 joints logged)."""
    folder = tmp_path_factory.mktemp("arm")
    urdf, _, files, _ = write_records(lab("chain"), folder)
    return urdf, files


def described(urdf: Path, folder: Path, mimic: bool) -> Path:
    path = folder / ("mimic.urdf" if mimic else "fingers.urdf")
    path.write_text(gripper(mimic)(urdf.read_text()))
    return path


@pytest.mark.parametrize("mimic", [False, True], ids=["branching", "mimic"])
def test_the_log_s_joints_determine_the_chain_of_a_gripper_urdf(records, tmp_path, mimic):
    urdf, _ = records
    path = described(urdf, tmp_path, mimic)
    assert logged_chain(path, 3) == (ARM, FINGERS)
    assert logged_chain(urdf, 3) is None  # a serial chain: read as before
    with pytest.raises(RobotDescriptionError, match="--joint-names"):
        logged_chain(path, 5)  # no chain of 5 joints from the base
    if mimic:  # the right finger follows the left: one chain of 4
        assert logged_chain(path, 4) == ((*ARM, "finger_left_joint"), ("finger_right_joint",))
    else:  # two fingers: two chains of 4
        with pytest.raises(RobotDescriptionError, match="2 chains of 4 joint.*--joint-names"):
            logged_chain(path, 4)
    arm = load_robot(urdf=path, joint_names=ARM)
    assert tuple(arm.joint_names) == ARM


#: the chain is read from the description before any record (:func:`logged_chain`, the same on either path): the mimic
#: gripper streamed runs in ``make test-slow``, ``make test`` reads it in memory and streams the branching one
@pytest.mark.parametrize(("mimic", "streamed"), [
    pytest.param(mimic, streamed, id=f"{'mimic' if mimic else 'branching'}-{'streamed' if streamed else 'in-memory'}",
                 marks=[pytest.mark.slow] if mimic and streamed else [])
    for mimic in (False, True) for streamed in (False, True)])
def test_identify_on_the_defaults_reads_the_logged_chain_and_predict_reads_the_same(records, tmp_path, mimic,
                                                                                    streamed):
    urdf, files = records
    path = described(urdf, tmp_path, mimic)
    named, chosen = tmp_path / "named.json", tmp_path / "chosen.json"
    more = ["--chunk-size", "500"] if streamed else []
    common = ["--urdf", str(path), "--data", str(files["train"]), "--validate", str(files["validate"]), *more]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        code, message = quiet(["identify", *common, "--joint-names", ",".join(ARM), "--out", str(named)])
        assert code == 0, message
        code, message = quiet(["identify", *common, "--out", str(chosen)])
    assert code == 0, message
    result = json.loads(chosen.read_text())
    assert result["logged_chain"]["joint_names"] == list(ARM)
    assert result["logged_chain"]["held_fixed"] == list(FINGERS)
    assert "--joint-names joint1,joint2,joint3" in result["logged_chain"]["reason"]
    assert result["model_file"]["robot"]["joint_names"] == list(ARM)
    told = json.loads(named.read_text())["model_file"]
    for key in told.keys() - {"preprocessing"}:  # the same answer as told (the preprocessing's timings apart)
        assert result["model_file"][key] == told[key], key
    predicted = []
    for model in (named, chosen):
        out = tmp_path / f"{model.stem}.csv"
        code, message = quiet(["predict", "--model", str(model), "--data", str(files["test"]), "--out", str(out)])
        assert code == 0, message
        predicted.append(pd.read_csv(out).to_numpy())
    np.testing.assert_array_equal(predicted[0], predicted[1])


@pytest.mark.parametrize("streamed", [False, True], ids=["in-memory", "streamed"])
def test_diagnose_on_the_defaults_says_the_chain(records, tmp_path, streamed):
    urdf, files = records
    path = described(urdf, tmp_path, False)
    out = tmp_path / "diagnosed.json"
    more = ["--chunk-size", "500"] if streamed else []
    with pytest.warns(UserWarning, match="read as the chain joint1,joint2,joint3"):
        code, message = quiet(["diagnose", "--urdf", str(path), "--data", str(files["train"]), "--validate",
                               str(files["validate"]), *more, "--out", str(out)])
    assert code == 0, message
    assert json.loads(out.read_text())["logged_chain"]["held_fixed"] == list(FINGERS)


@pytest.mark.parametrize("verb", ["identify", "diagnose"])
def test_a_tree_the_log_does_not_determine_still_exits_naming_the_option(records, tmp_path, verb):
    """Four logged joints and two fingers: two chains fit; the exit names --joint-names with both."""
    urdf, files = records
    path = described(urdf, tmp_path, False)
    four = {}
    for role in ("train", "validate"):
        table = pd.read_csv(files[role])
        table["q4"], table["tau4"] = 0.0, 0.0
        four[role] = tmp_path / f"{role}4.csv"
        table.to_csv(four[role], index=False)
    code, message = quiet([verb, "--urdf", str(path), "--data", str(four["train"]), "--validate",
                           str(four["validate"]), "--out", str(tmp_path / "r.json")])
    assert code != 0
    assert "--joint-names" in message and "joint1,joint2,joint3,finger_left_joint" in message
