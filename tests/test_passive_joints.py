"""Passive (unactuated) joints: a joint no motor drives has zero torque by physics, and its row of the inverse
dynamics, ``0 = Y_j θ`` with its own friction, is an equation of the fit (:mod:`estimation.data.passive`).

Slow cases, simulated by :mod:`tests.passive_simulation` (the actuated joints' Fourier motion, the passive joint
integrated under the true dynamics; train, validate and test records of different motions; white noise of 2 % of
each driven channel's spread), each run as the other ``tests/test_unseen_robot*`` files run theirs: the default
``oed identify`` (told the plain fit's model class) and ``oed diagnose``, then ``oed predict`` on the test record no
choice saw, against the plain Pinocchio least-squares fit of ``benchmarks/bench_real_robots.py`` set up the same way
(the passive joint's row an equation of zero in its stacked least squares): per joint within 1.3x, in total at most
1.0x (each with its noise floor's sampling allowance), ``oed predict`` reproducing each verb's validation error
(relative 1e-6), no effect named beyond the truth's:

- a PUMA 3 whose third joint is passive (a free elbow), named with ``--passive 3``, the log without ``tau3``;
- a Pendubot (two links in a vertical plane, the elbow free) whose URDF declares a ``<transmission>`` on the shoulder
  only: the elbow is read as passive from the description, the log without ``tau2``.

Cheap checks: the passive row makes parameters identifiable (Pinocchio's regressor, independent of the toolkit); the
reader, the missing column's message, the descriptions' motors, the weighted fit, ``oed design``'s refusal.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dynamics.robots import described_unactuated, load_robot
from tests.passive_simulation import Passive, write_passive_records
from tests.test_one_answer_audit import RELATIVE
from tests.test_unseen_robot_benches import written
from tests.test_unseen_robot_kinds import as_well_as_the_plain_fit, named_law, quiet
from tests.test_unseen_robot_labs import puma, verbs_against_the_plain_fit
from tests.test_unseen_robots import NOISE

PENDUBOT = """<?xml version="1.0"?>
<robot name="pendubot">
  <link name="world"/>
  <joint name="stand" type="fixed"><origin xyz="0 0 1.0"/><parent link="world"/><child link="hub"/></joint>
  <link name="hub"><inertial><origin xyz="0 0 0"/><mass value="2"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <joint name="shoulder" type="revolute"><origin xyz="0 0.04 0"/><axis xyz="0 1 0"/><parent link="hub"/><child link="upper"/>
    <limit lower="-2.5" upper="2.5" velocity="4.0" effort="30"/></joint>
  <link name="upper"><inertial><origin xyz="0.15 0 0.005"/><mass value="1.2"/><inertia ixx="0.002" ixy="0" ixz="0" iyy="0.012" iyz="0" izz="0.011"/></inertial></link>
  <joint name="elbow" type="revolute"><origin xyz="0.3 0.03 0"/><axis xyz="0 1 0"/><parent link="upper"/><child link="fore"/>
    <limit lower="-6.3" upper="6.3" velocity="12.0" effort="10"/></joint>
  <link name="fore"><inertial><origin xyz="0.12 0 -0.004"/><mass value="0.6"/><inertia ixx="0.0008" ixy="0" ixz="0" iyy="0.004" iyz="0" izz="0.0037"/></inertial></link>
  <transmission name="shoulder_transmission"><type>transmission_interface/SimpleTransmission</type>
    <joint name="shoulder"><hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface></joint>
    <actuator name="shoulder_motor"><mechanicalReduction>1</mechanicalReduction></actuator></transmission>
</robot>
"""


def pendubot():
    return load_robot(urdf=written(PENDUBOT))


CASES = {
    "puma3": Passive("PUMA 3 joints, the third passive (--passive 3), 12 s / 5 s / 8 s at 250 Hz, no dq", puma(3), 2),
    "pendubot": Passive("a Pendubot (the elbow passive by its URDF: a transmission on the shoulder only), 12 s / 5 s "
                        "/ 8 s at 250 Hz, no dq, the elbow's bearing light (viscous 0.02 N m s)", pendubot, 1,
                        passive_viscous=0.02),
}


def run_case(case: Passive, folder: Path, options: tuple[str, ...], urdf_text: str | None = None) -> dict:
    """Write the records, run the verbs and the plain fit (:func:`tests.test_unseen_robot_labs.run_lab`'s steps)."""
    from benchmarks.bench_real_robots import PlainFit

    urdf, records, files, spread = write_passive_records(case, folder, urdf_text=urdf_text)
    plain = PlainFit(["--urdf", str(urdf)])
    cutoff, theta = plain.fit(records["train"], records["validate"], rate_hz=case.rate_hz)
    predicted_plain, kept = plain.predict(records["test"], cutoff, theta)
    outcome = verbs_against_the_plain_fit(urdf, files, records["test"], kept, predicted_plain, folder,
                                          options=options)
    return {**outcome, "cutoff": cutoff, "floor": (NOISE * spread) ** 2}


def judged(name: str, outcome: dict) -> None:
    as_well_as_the_plain_fit(name, outcome, f"chosen {outcome['selections']}; ")
    for label, error in outcome["reproduced"].items():
        assert error < RELATIVE, (label, error)
    for label, named in outcome["effects"].items():
        false = [effect for effect in named if named_law(effect) not in ("coulomb", "viscous", "offset")]
        assert not false, (label, false)


@pytest.mark.slow
def test_a_puma_with_a_passive_third_joint_predicts_as_well_as_a_plain_fit(tmp_path):
    """``--passive 3`` on a log without ``tau3``: the defaults within the plain fit's margins on the test record,
    ``result.json`` and the model file naming the passive joint, ``oed predict`` reproducing each reported error."""
    outcome = run_case(CASES["puma3"], tmp_path, ("--passive", "3"))
    judged(CASES["puma3"].name, outcome)
    for label in ("default", "diagnose"):
        document = json.loads((tmp_path / f"{label}.json").read_text())
        assert document["passive_joints"]["joints"] == ["joint3"], document.get("passive_joints")
        assert document["passive_joints"]["named"] == ["3"] and document["passive_joints"]["described"] == []
        assert document["model_file"]["robot"]["passive"] == ["joint3"]


@pytest.mark.slow
def test_a_pendubots_free_elbow_is_read_from_its_description_and_predicts_as_well_as_a_plain_fit(tmp_path):
    """The URDF's transmission drives the shoulder only and the log has no ``tau2``: the elbow is read as passive
    (said in the summary and ``result.json``, with the option that says so), and the defaults predict the test record
    as well as the plain fit."""
    outcome = run_case(CASES["pendubot"], tmp_path, (), urdf_text=PENDUBOT)
    judged(CASES["pendubot"].name, outcome)
    for label in ("default", "diagnose"):
        document = json.loads((tmp_path / f"{label}.json").read_text())
        assert document["passive_joints"]["described"] == ["elbow"], document.get("passive_joints")
        assert document["model_file"]["robot"]["passive"] == ["elbow"]


def test_the_passive_row_makes_parameters_identifiable():
    """Pinocchio's regressor of a PUMA 3 (rigid body, viscous, Coulomb) on random states: the rows of the two
    driven joints alone determine fewer parameter combinations than with the passive joint's row ``0 = Y_3 θ``; its
    friction (``fv3``, ``fc3``) is determined only with it."""
    import pinocchio as pin
    from scipy.linalg import qr

    from dynamics.pinocchio_bridge import to_pinocchio

    robot = load_robot("puma560", joints=3)
    model = to_pinocchio(robot)
    data = model.createData()
    generator = np.random.default_rng(0)
    n = robot.n_joints
    rows = []
    for _ in range(200):
        q, dq, ddq = (generator.uniform(-np.pi, np.pi, n) for _ in range(3))
        Y = np.zeros((n, 12 * n))
        Y[:, :10 * n] = pin.computeJointTorqueRegressor(model, data, q, dq, ddq)
        Y[np.arange(n), 10 * n + np.arange(n)] = dq
        Y[np.arange(n), 11 * n + np.arange(n)] = np.sign(dq)
        rows.append(Y)
    stacked = np.array(rows)

    def rank(Y: np.ndarray) -> int:
        R = qr(Y, mode="r", pivoting=True)[0]
        return int(np.sum(np.abs(np.diag(R)) > 1e-8 * abs(R[0, 0])))

    driven = stacked[:, :2].reshape(-1, 12 * n)
    every = stacked.reshape(-1, 12 * n)
    assert rank(every) > rank(driven), (rank(every), rank(driven))
    for column in (10 * n + 2, 11 * n + 2):  # fv3, fc3: zero on the driven rows, determined by the passive row
        assert not driven[:, column].any() and every[:, column].any()


def _log(path: Path, with_tau3: bool = False) -> Path:
    t = np.arange(0.0, 2.0, 0.004)
    table = {"t": t, **{f"q{j}": 0.3 * np.sin(2 * np.pi * 0.5 * j * t) for j in (1, 2, 3)},
             "tau1": np.cos(t), "tau2": np.sin(t)}
    if with_tau3:
        table["tau3"] = 0.01 + 0.0 * t
    pd.DataFrame(table).to_csv(path, index=False)
    return path


def test_the_reader_gives_a_passive_joint_zero_torque_and_names_the_option_when_a_column_is_missing(tmp_path):
    """A log without ``tau3``: read for a robot whose third joint is passive, ``tau3`` is zero at every sample; for
    the robot without it, the error names the column and ``--passive`` and says a driven joint's torque is unknown,
    not zero. A logged column of a passive joint is not read (a warning says so)."""
    from dynamics.models import build_model
    from estimation.data import read_record
    from estimation.data.loading import MissingColumnError
    from estimation.data.passive import PassiveJointWarning

    path = _log(tmp_path / "log.csv")
    passive = build_model(load_robot("puma560", joints=3, passive=["joint3"]), "internal", "viscous")
    (record,) = read_record(path, model=passive)
    assert record.tau.shape[1] == 3 and not record.tau[:, 2].any() and record.tau[:, 0].any()
    driven = build_model(load_robot("puma560", joints=3), "internal", "viscous")
    with pytest.raises(MissingColumnError, match=r"no torque column tau3 .*--passive JOINT.*unknown, not zero"):
        read_record(path, model=driven)
    with pytest.warns(PassiveJointWarning, match="tau3 of the passive joint"):
        (record,) = read_record(_log(tmp_path / "logged.csv", with_tau3=True), model=passive)
    assert not record.tau[:, 2].any()


def test_the_descriptions_say_which_joints_have_no_motor(tmp_path):
    """A URDF's ``<transmission>`` on some joints, an MJCF's ``<actuator>`` on some: the others are without a motor;
    a description that declares none says nothing; a joint named passive that the robot lacks is refused by name."""
    from dynamics.errors import RobotDescriptionError

    assert described_unactuated(written(PENDUBOT), pendubot()) == ("elbow",)
    plain = PENDUBOT[:PENDUBOT.index("  <transmission")] + "</robot>\n"
    assert described_unactuated(written(plain), load_robot(urdf=written(plain))) == ()
    mjcf = tmp_path / "arm.xml"
    mjcf.write_text("""<mujoco model="two"><worldbody><body name="a" pos="0 0 1">
      <joint name="j1" type="hinge" axis="0 1 0"/><inertial pos="0.1 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>
      <body name="b" pos="0.2 0 0"><joint name="j2" type="hinge" axis="0 1 0"/>
      <inertial pos="0.1 0 0" mass="0.5" diaginertia="0.005 0.005 0.005"/></body></body></worldbody>
      <actuator><motor joint="j1" gear="10"/></actuator></mujoco>""")
    assert described_unactuated(mjcf, load_robot(urdf=mjcf)) == ("j2",)
    assert load_robot(urdf=mjcf, passive=["2"]).passive_joints == ("j2",)
    with pytest.raises(RobotDescriptionError, match="passive joint 'wrist'.*j1, j2"):
        load_robot(urdf=mjcf, passive=["wrist"])


def test_a_weighted_fit_weights_a_passive_channel_by_its_residual_and_refuses_a_dead_one():
    """A channel of zeros: refused as a dead sensor unless it is a passive joint's, which the weighted fit then
    weights by its residual (finite weights, the estimate of the driven channels' and the zero row's truth)."""
    from estimation.estimators import IdentificationProblem, WeightedLeastSquares

    generator = np.random.default_rng(1)
    Y = generator.normal(size=(400, 3, 4))
    theta = np.array([1.0, -2.0, 0.5, 3.0])
    Y[:, 2, 3] = -(Y[:, 2, :3] @ theta[:3]) / theta[3]  # the third row: 0 = Y_3 θ exactly
    y = np.einsum("nmr,r->nm", Y, theta) + generator.normal(0.0, 0.01, (400, 3))
    y[:, 2] = 0.0
    names = ("a", "b", "c", "d")
    with pytest.raises(ValueError, match="tau3 read zero in every sample"):
        WeightedLeastSquares().fit(IdentificationProblem(Y, y, ("tau1", "tau2", "tau3"), names))
    fitted = WeightedLeastSquares().fit(IdentificationProblem(Y, y, ("tau1", "tau2", "tau3"), names,
                                                              passive=("tau3",)))
    assert np.all(np.isfinite(fitted.theta_))
    np.testing.assert_allclose(fitted.theta_, theta, rtol=0.01)


def test_design_refuses_a_passive_joint_by_name(tmp_path):
    """``oed design --passive``: a passive joint's motion is no command; the error names it (exit 2, no work)."""
    code, message = quiet(["design", "--robot", "puma560", "--joints", "3", "--passive", "joint3", "--out",
                           str(tmp_path / "design.json")])
    assert code == 2 and "passive joint(s) joint3" in message and "Traceback" not in message, message


def test_an_exported_urdf_keeps_the_passive_joints_without_a_motor(tmp_path):
    """The URDF written from a robot with a passive joint (:func:`dynamics.urdf_export.robot_urdf`, or the user's file
    with the identified bodies, :func:`~dynamics.urdf_export.urdf_with_inertials`) declares a motor on each driven joint
    only, so that reading it again says which joint has none; a robot without a passive joint, or a file that declares
    its motors, is written as before."""
    from dynamics.urdf_export import robot_urdf, urdf_with_inertials

    passive = load_robot("puma560", joints=3, passive=["joint3"])
    written_back = tmp_path / "puma.urdf"
    written_back.write_text(robot_urdf(passive))
    assert described_unactuated(written_back, load_robot(urdf=written_back)) == ("joint3",)
    assert "<transmission" not in robot_urdf(load_robot("puma560", joints=3))
    plain = PENDUBOT[:PENDUBOT.index("  <transmission")] + "</robot>\n"
    free_elbow = load_robot(urdf=written(plain), passive=["elbow"])
    merged = tmp_path / "pendubot.urdf"
    merged.write_text(urdf_with_inertials(plain, free_elbow, free_elbow.standard_parameters))
    assert described_unactuated(merged, load_robot(urdf=merged)) == ("elbow",)
    assert urdf_with_inertials(PENDUBOT, free_elbow, free_elbow.standard_parameters).count("<transmission") == 1
    np.testing.assert_allclose(load_robot(urdf=merged).standard_parameters, free_elbow.standard_parameters, atol=1e-12)
