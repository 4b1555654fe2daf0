"""Motor-side friction a candidate of the default ``oed identify`` when the declared transmission couples motors
(:mod:`estimation.consistent.motor_friction`).

A simulated PUMA with the TX40's coupled wrist (motor 6 turns with ``q5 + q6``), logged on the motor side and
declared with ``--transmission`` (:func:`tests.test_unseen_robot_realities.write_records`), the user's friction the
per-joint ``viscous,coulomb,offset``:

* the truth holds motor 6's own viscous and Coulomb friction (felt by joints 5 and 6): the default answer takes
  ``motor_viscous@6`` and ``motor_coulomb@6`` and predicts the test record better than the default with per-joint
  friction alone (the same run with the candidate left out), and ``oed predict`` reproduces the validation error it
  reports, ``oed export`` writes it;
* the truth's friction is per joint: the candidate does no harm (the test error within 2 % of the per-joint
  default's);
* without a coupled transmission nothing is added (:func:`motor_friction_laws`).

The two simulated cases take about 35 s each (four identifications): ``slow``."""

from __future__ import annotations

import json

import numpy as np
import pytest

import oed
import oed.workflows.identify as identify_workflow
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.transmission import Transmission
from estimation.consistent.motor_friction import motor_friction_laws
from oed.cli import main
from tests.test_unseen_robot_realities import Reality, puma6, transmission_matrix, write_records
from tests.test_unseen_robots import FRICTION, Log

LOG = Log(6.0, 500.0, velocity=False)


def reality(extra: str) -> Reality:
    return Reality(f"PUMA 6 joints, coupled wrist, {extra or 'per-joint friction'}", puma6, LOG,
                   Log(3.0, 500.0, velocity=False), Log(4.0, 500.0, velocity=False), extra=extra, motor_side=True)


def identified(folder, files, options, label: str) -> tuple[dict, dict[str, float], dict[str, float]]:
    """The default ``oed identify`` written to ``label.json``: its document, and ``oed predict``'s MSE on the
    validation and test records."""
    run = oed.identify(urdf=folder / "robot.urdf", data=(files["train"],), validate=(files["validate"],),
                       friction=FRICTION, transmission=options[options.index("--transmission") + 1])
    out = folder / f"{label}.json"
    run.write(out)
    errors = []
    for role in ("validate", "test"):
        metrics = folder / f"{label}_{role}_metrics.json"
        assert main(["predict", "--model", str(out), "--data", str(files[role]), "--out",
                     str(folder / f"{label}_{role}.csv"), "--metrics", str(metrics)]) == 0
        errors.append(json.loads(metrics.read_text())["mse"])
    return json.loads(out.read_text()), errors[0], errors[1]


def both_defaults(extra: str, folder, monkeypatch) -> tuple[tuple, tuple]:
    """The default with the motor-friction candidate, and the same run with it left out (per-joint friction alone)."""
    _, _, files, _, options = write_records(reality(extra), folder)
    default = identified(folder, files, options, "default")
    with monkeypatch.context() as patch:
        patch.setattr(identify_workflow, "motor_friction_laws", lambda model, transmission: ())
        per_joint = identified(folder, files, options, "per_joint")
    return default, per_joint


def total(mse: dict[str, float]) -> float:
    return float(sum(mse.values()))


@pytest.mark.slow
def test_motor_friction_truth_the_default_takes_it_and_predicts_better(tmp_path, monkeypatch):
    (document, validation, test), (_, _, per_joint_test) = both_defaults("coupled motor friction", tmp_path,
                                                                           monkeypatch)
    specs = {effect["spec"] for effect in document["model_file"]["effect_values"]}
    assert {"motor_viscous@6", "motor_coulomb@6"} <= specs, specs
    assert "motor-side friction on the coupled motors" in document["model_selection"]["reason"]
    assert document["model_selection"]["reason"].endswith("taken")
    # better on the test record: in total and on the coupled joints
    assert total(test) < 0.8 * total(per_joint_test), (test, per_joint_test)
    assert test["tau5"] < 0.5 * per_joint_test["tau5"], (test, per_joint_test)
    # one answer: predict reproduces the validation error the result reports for its chosen model
    reported = document["validation"]["chosen"]["mse"] if "chosen" in document["validation"] \
        else document["validation"]["mse"]
    assert max(abs(validation[c] / reported[c] - 1) for c in reported) < 1e-6, (validation, reported)
    urdf, friction = tmp_path / "exported.urdf", tmp_path / "friction.json"
    assert main(["export", "--model", str(tmp_path / "default.json"), "--urdf", str(urdf), "--friction",
                 str(friction)]) == 0
    assert urdf.exists() and friction.exists()


@pytest.mark.slow
def test_per_joint_friction_truth_the_candidate_does_no_harm(tmp_path, monkeypatch):
    (document, _, test), (_, _, per_joint_test) = both_defaults("", tmp_path, monkeypatch)
    assert "motor-side friction on the coupled motors" in document["model_selection"]["reason"]
    assert total(test) <= 1.02 * total(per_joint_test), (test, per_joint_test)


def test_no_coupled_transmission_adds_nothing():
    robot = load_robot("puma560", joints=6)
    model = build_model(robot, "internal", FRICTION)
    assert motor_friction_laws(model, None) == ()
    diagonal = Transmission(np.diag(np.arange(1.0, 7.0)))
    assert diagonal.coupled_motors() == () and motor_friction_laws(model, diagonal) == ()
    coupled = Transmission(transmission_matrix())
    assert coupled.coupled_motors() == (5,)
    laws = motor_friction_laws(model, coupled)
    assert [(law.kind, law.labels) for law in laws] == [("viscous", ("m6",)), ("coulomb", ("m6",))]
    declared = build_model(robot, "internal", (*model.effects, laws[0]))
    assert [(law.kind, law.labels) for law in motor_friction_laws(declared, coupled)] == [("coulomb", ("m6",))]
    assert motor_friction_laws(build_model(robot, "external", ()), coupled) == ()
