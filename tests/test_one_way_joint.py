"""A declared Coulomb friction the training record cannot tell from the offset (issue 34): joint 2 of a 1.2 s
training record moves one way only, so its Coulomb and offset columns are one there
(:mod:`estimation.identification.undetermined`).

Measured at 74a5e1a on this record: ``oed identify --friction viscous,coulomb,offset`` exited ("the data do not
determine parameter(s) ['fc2', 'off2']"), and so did the default ``oed diagnose`` and ``oed identify`` on the 1.5 s
record cut before joint 2 reverses ("float() argument must be ... not 'NoneType'": a derivative candidate without a
score, :func:`estimation.preprocessing.plan.best_filter`)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.identification.undetermined import merged_one_way
from tests.test_one_answer_audit import RELATIVE
from tests.test_unseen_robot_kinds import as_well_as_the_plain_fit
from tests.test_unseen_robot_logs import LoggedAs, lab, run_logged


def test_the_coulomb_column_of_a_joint_that_does_not_reverse_is_merged_into_its_offset():
    model = build_model(load_robot("puma560", joints=3), "internal", "viscous,coulomb,offset")
    effects, merged = merged_one_way(model, ("fc2", "off2"))
    assert [(effect.name, effect.joints) for effect in effects] == [("viscous", None), ("coulomb", (0, 2)),
                                                                     ("offset", None)]
    assert [(column.joint, column.parameter, column.merged_into) for column in merged] == [(2, "fc2", "off2")]
    assert "fc2 is left out (not determined) and off2 holds their sum" in merged[0].statement()
    rebuilt = build_model(model.robot, "internal", effects)
    assert "fc2" not in rebuilt.parameter_names and {"fc1", "fc3", "off2"} <= set(rebuilt.parameter_names)
    # anything else the data do not determine stays the error it is
    assert merged_one_way(model, ("fc2", "off2", "Izz1R")) is None
    assert merged_one_way(model, ("fc2",)) is None
    without_offset = build_model(model.robot, "internal", "viscous,coulomb")
    assert merged_one_way(without_offset, ("fc2", "off2")) is None


ONE_WAY = LoggedAs("1.2 s training record, joint 2 one way", lab("short", train=1.2))


@pytest.mark.slow
def test_a_declared_coulomb_friction_of_a_joint_that_does_not_reverse_is_said_not_an_exit(tmp_path):
    """The declared model is fitted with fc2 merged into off2 (a warning naming joint 2, ``not_determined`` in
    ``result.json``); both verbs predict the test record (where joint 2 reverses) as well as the plain fit."""
    outcome = run_logged(ONE_WAY, tmp_path)
    as_well_as_the_plain_fit(ONE_WAY.name, outcome, f"chosen {outcome['selections']}; ")
    for label, error in outcome["reproduced"].items():
        assert error <= RELATIVE, (label, error)
    document = json.loads((tmp_path / "default.json").read_text())
    assert [(item["parameter"], item["merged_into"]) for item in document["not_determined"]] == [("fc2", "off2")]
    assert any("joint 2 (joint2) does not reverse in the training record" in text for text in document["warnings"])
    names = [row["name"] for row in document["parameters"]]
    assert "fc2" not in names and "off2" in names and np.isfinite(len(names))


def test_the_best_filter_passes_over_a_candidate_without_a_score():
    """A derivative candidate whose fit failed is written with ``score: null``: at 74a5e1a ``best_filter`` read it
    as ``float(None)`` and the default diagnose and identify exited on the 1.5 s record cut before joint 2
    reverses."""
    from estimation.preprocessing.plan import best_filter

    document = {"candidates": [{"method": "butterworth", "cutoff_hz": 5.0, "score": None},
                               {"method": "butterworth", "cutoff_hz": 10.0, "score": 2.0}]}
    assert best_filter(document).cutoff_hz == 10.0
    assert best_filter({"candidates": document["candidates"][:1]}) is None


@pytest.mark.slow
def test_diagnose_told_coulomb_and_offset_merges_them_in_memory(tmp_path):
    import oed
    from tests.test_unseen_robot_labs import write_records

    _, _, files, _ = write_records(ONE_WAY.lab, tmp_path)
    run = oed.diagnose(urdf=tmp_path / "robot.urdf", data=files["train"], validate=files["validate"],
                       friction="viscous,coulomb,offset")
    document = run.to_dict()
    assert [(item["parameter"], item["merged_into"]) for item in document["not_determined"]] == [("fc2", "off2")]
    assert any("joint 2 (joint2) does not reverse" in text for text in run.warnings)


@pytest.mark.slow
def test_the_streamed_diagnose_told_coulomb_and_offset_merges_them_as_in_memory(tmp_path):
    """The streamed ``oed diagnose`` (``--chunk-size 100``) exited on the rank deficiency at 7f2677d; now it merges
    fc2 into off2 as in memory: the same warning, ``not_determined``, model and validation errors."""
    import oed
    from tests.test_unseen_robot_labs import write_records

    _, _, files, _ = write_records(ONE_WAY.lab, tmp_path)
    documents = {}
    for label, chunk in (("memory", {}), ("streamed", {"chunk_size": 100})):
        run = oed.diagnose(urdf=tmp_path / "robot.urdf", data=files["train"], validate=files["validate"],
                           friction="viscous,coulomb,offset", **chunk)
        assert any("joint 2 (joint2) does not reverse" in text for text in run.warnings), label
        documents[label] = run.to_dict()
    memory, streamed = documents["memory"], documents["streamed"]
    assert streamed["diagnosis_path"] != memory["diagnosis_path"]
    assert streamed["not_determined"] == memory["not_determined"]
    assert [(item["parameter"], item["merged_into"]) for item in streamed["not_determined"]] == [("fc2", "off2")]
    assert streamed["model_file"]["effects"] == memory["model_file"]["effects"] == "viscous,coulomb@1+3,offset"
    for channel, error in memory["validation"]["after"]["mse"].items():
        assert streamed["validation"]["after"]["mse"][channel] == pytest.approx(error, rel=1e-6), channel
