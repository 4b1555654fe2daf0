"""Robots whose reality changes between the records, or holds what no rigid model does (issue 34), beside the other
unseen-robot modules (:mod:`tests.test_unseen_robots`, ``_kinds``, ``_realities``, ``_labs``, ``_logs``, ``_cells``,
``_mounts``, ``_rigs``, ``_benches``), run by the same verbs and plain fit
(:func:`tests.test_unseen_robot_labs.verbs_against_the_plain_fit`) (h-unseen11):

- a 7-joint arm one of whose joints is held still through the training and validation records (its columns
  unidentifiable there) and moves in the test;
- a belt-driven base joint: the encoder on the motor, the link behind an elastic belt (a second mode at 8 Hz, 5 %
  damping), the torque sensed at the joint;
- torques logged as motor currents: an unknown gain per joint and one joint's sign flipped;
- a gripper that picks up a 2 kg payload between the training and the test (the test holds it, nothing says so);
- a tool pressed on a table for one second of the training record (a 40 N wrench outside the model);
- a mobile-base arm whose base stands level while trained and 2° off level in the test (gravity's direction off).

No data are copied; every record is simulated here: the plain fit's model class (the description's bodies ±20 %,
:func:`tests.test_unseen_robots.truth`), each case's reality, white torque noise of 2 % of each channel's spread.
Training and validation are Fourier motions of different seeds, the test a point-to-point motion with rests (another
kind of motion). Each case runs the default ``oed identify`` (told the plain fit's model class) and ``oed diagnose``
(its own defaults), then ``oed predict`` on the test record no choice saw, against the plain Pinocchio least-squares
fit of ``benchmarks/bench_real_robots.py`` (its cut-off chosen on the validation record) on the same recorded
samples: per joint within 1.3x, in total at most 1.0x, each figure allowed its noise floor's sampling spread; and
``oed predict`` on the validation record reproduces the validation error each verb reported (relative 1e-6)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import json
import re

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.urdf_export import robot_urdf
from oed.fourier import random_fourier
from tests.test_one_answer_audit import RELATIVE
from tests.test_unseen_robot_kinds import as_well_as_the_plain_fit, marks, point_to_point
from tests.test_unseen_robot_labs import verbs_against_the_plain_fit
from tests.test_unseen_robot_mounts import rotation
from tests.test_unseen_robot_rigs import seven_joint_urdf
from tests.test_unseen_robots import FRICTION, NOISE, Log, logged, times, truth

PI = np.pi
ROLES = (("train", 11), ("validate", 12), ("test", 13))


def puma_urdf(joints: int) -> Callable[[], str]:
    return lambda: robot_urdf(load_robot("puma560", joints=joints))


@dataclass(frozen=True)
class Changed:
    """One case: the robot's URDF (its true kinematics; the bodies drawn ±20 % about its inertials), the log of
    each role, and what the robot and its logger hold beyond the plain class."""

    name: str
    urdf: Callable[[], str]
    train: Log
    validate: Log
    test: Log
    held: int = 0  # a joint (1-based) held still at its range's centre in the training and validation records
    belt: tuple[int, float] = ()  # (joint, Hz): the joint's link behind an elastic belt, the encoder on the motor
    gains: tuple[float, ...] = ()  # torques logged as currents: tau_j * gain_j (A per N m), a negative gain a flip
    payload: float = 0.0  # kg held in the test record only, 0.1 m along the last link's z
    contact: float = 0.0  # N: the table pushing up on the last joint's frame for 1 s in the training record
    tilt: float = 0.0  # degrees: the base off level in the test record only
    said: str = ""  # a pattern one of `oed identify`'s warnings must match (what the user is told)
    unsaid: str = ""  # a pattern none of either verb's warnings may match (what the truth does not hold)
    shaped: tuple[str, ...] = ()  # effects beyond the plain class the diagnosis may name ("sigmoid on tau1"): a
    # family of the truth's own law at another shape
    slow: bool = True
    xfail: str = ""
    #: the verbs whose model's estimate of the change `oed predict` gives more than three standard deviations off the
    #: truth (held as measured: the test fails when it comes within them)
    estimate_missed: tuple[str, ...] = ()


def motion_limits(robot) -> SimpleNamespace:
    """The joints' ranges a motion keeps to: the description's, a continuous joint's taken as ±90°."""
    lower = np.where(np.isfinite(robot.lower), robot.lower, -PI / 2)
    upper = np.where(np.isfinite(robot.upper), robot.upper, PI / 2)
    return SimpleNamespace(n_joints=robot.n_joints, lower=np.asarray(lower, float), upper=np.asarray(upper, float),
                           velocity_limit=np.asarray(robot.velocity_limit, float))


def with_payload(model, theta: np.ndarray, mass: float, distance: float = 0.1) -> np.ndarray:
    """``theta`` with a point mass ``mass`` held ``distance`` along the last link's ``z`` (its first moment and
    its inertia about the link's frame)."""
    names, n, out = list(model.parameter_names), model.robot.n_joints, theta.copy()
    for name, value in (("m", mass), ("mz", mass * distance), ("Ixx", mass * distance**2),
                        ("Iyy", mass * distance**2)):
        out[names.index(f"{name}{n}")] += value
    return out


def contact_torque(urdf: Path, q: np.ndarray, force: float, inside: np.ndarray) -> np.ndarray:
    """``J(q)ᵀ f`` of an upward force ``force`` (N, the world's ``z``) on the last joint's frame, on the samples
    ``inside``; zero elsewhere (Pinocchio's Jacobian, ``LOCAL_WORLD_ALIGNED``)."""
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    out = np.zeros_like(q)
    for index in np.flatnonzero(inside):
        pin.computeJointJacobians(model, data, q[index])
        jacobian = pin.getJointJacobian(model, data, model.njoints - 1, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        out[index] = jacobian[2] * force
    return out


def behind_a_belt(model, theta: np.ndarray, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, t: np.ndarray,
                  joint: int, hz: float, damping: float = 0.05) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The link's motion behind an elastic belt when the motor follows ``q``: the deflection ``δ`` of joint
    ``joint`` (0-based) obeys ``M_jj (q̈_m − δ̈) + b_j = k δ + c δ̇`` (``k = M̄_jj (2π hz)²``, ``c`` of ``damping``
    critical), ``M_jj`` and ``b_j`` taken along the motor's motion (δ of a few mrad), integrated semi-implicitly at
    the record's steps; ``(q_link, dq_link, ddq_link)``."""
    accelerated = ddq.copy()
    accelerated[:, joint] += 1.0
    still = ddq.copy()
    still[:, joint] = 0.0
    bias = model.predict(theta, q, dq, still)[:, joint]
    inertia = model.predict(theta, q, dq, accelerated)[:, joint] - model.predict(theta, q, dq, ddq)[:, joint]
    omega = 2 * PI * hz
    stiffness = float(np.mean(inertia)) * omega**2
    friction = 2.0 * damping * float(np.mean(inertia)) * omega
    delta, rate = np.zeros(t.shape[0]), np.zeros(t.shape[0])
    acceleration = np.zeros(t.shape[0])
    delta[0] = bias[0] / stiffness  # at rest on the spring
    for index in range(t.shape[0]):
        acceleration[index] = ddq[index, joint] + (bias[index] - stiffness * delta[index]
                                                   - friction * rate[index]) / inertia[index]
        if index + 1 < t.shape[0]:
            step = t[index + 1] - t[index]
            rate[index + 1] = rate[index] + step * acceleration[index]
            delta[index + 1] = delta[index] + step * rate[index + 1]
    q_link, dq_link, ddq_link = q.copy(), dq.copy(), ddq.copy()
    q_link[:, joint] -= delta
    dq_link[:, joint] -= rate
    ddq_link[:, joint] -= acceleration
    return q_link, dq_link, ddq_link


def write_records(case: Changed, folder: Path) -> tuple[Path, dict, dict, np.ndarray]:
    """The description and the records of each role as the lab's logger writes them: ``(urdf, records, files,
    spread)``."""
    from benchmarks.bench_real_robots import Record

    urdf = folder / "robot.urdf"
    urdf.write_text(case.urdf())
    robot = load_robot(urdf=urdf)
    model = build_model(robot, "internal", FRICTION)
    theta = truth(model)
    limits = motion_limits(robot)
    spread, records, files = None, {}, {}
    for role, seed in ROLES:
        log = getattr(case, role)
        generator = np.random.default_rng(1000 + seed)
        t = times(log, generator)
        if role == "test":
            q, dq, ddq = point_to_point(limits, seed, t)
        else:
            q, dq, ddq = random_fourier(limits, seed=seed, frequency_hz=log.motion_hz).evaluate(t)
        if case.held and role != "test":
            j = case.held - 1
            q[:, j], dq[:, j], ddq[:, j] = 0.5 * (limits.lower[j] + limits.upper[j]), 0.0, 0.0
        truth_model, truth_theta, q_link, dq_link, ddq_link = model, theta, q, dq, ddq
        if case.payload and role == "test":
            truth_theta = with_payload(model, theta, case.payload)
        if case.tilt and role == "test":
            gravity = rotation(0.0, np.radians(case.tilt), 0.0).T @ np.array([0.0, 0.0, -9.81])
            truth_model = build_model(robot.with_gravity(gravity), "internal", FRICTION)
        if case.belt:
            q_link, dq_link, ddq_link = behind_a_belt(model, theta, q, dq, ddq, t, case.belt[0] - 1, case.belt[1])
        tau = truth_model.predict(truth_theta, q_link, dq_link, ddq_link)
        if case.contact and role == "train":
            middle = 0.5 * (t[0] + t[-1])
            tau = tau - contact_torque(urdf, q, case.contact, np.abs(t - middle) < 0.5)
        if spread is None:
            spread = tau.std(axis=0)
        tau = tau + generator.normal(0.0, 1.0, tau.shape) * NOISE * spread
        if case.gains:
            tau = tau * np.asarray(case.gains)
        t, q, dq, tau, frame = logged(t, q, dq, tau, log, generator)
        files[role] = folder / f"{role}.csv"
        pd.DataFrame(frame).to_csv(files[role], index=False, float_format="%.10g")
        records[role] = Record(t, q, tau, dq if log.velocity else None)
    if case.gains:
        spread = spread * np.abs(np.asarray(case.gains))
    return urdf, records, files, spread


def run_changed(case: Changed, folder: Path) -> dict:
    """Write the records, run the verbs and the plain fit: per joint test MSE of each on the same samples, and
    whether ``oed predict`` reproduces each verb's reported validation error."""
    from benchmarks.bench_real_robots import PlainFit

    urdf, records, files, spread = write_records(case, folder)
    plain = PlainFit(["--urdf", str(urdf)])
    cutoff, plain_theta = plain.fit(records["train"], records["validate"], rate_hz=case.train.rate_hz)
    predicted_plain, kept = plain.predict(records["test"], cutoff, plain_theta)
    outcome = verbs_against_the_plain_fit(urdf, files, records["test"], kept, predicted_plain, folder)
    return {**outcome, "cutoff": cutoff, "floor": (NOISE * spread) ** 2}


def logs(seconds: tuple[float, float, float] = (10.0, 4.0, 6.0), rate: float = 250.0, **more) -> tuple[Log, ...]:
    return tuple(Log(duration, rate, velocity=False, **more) for duration in seconds)


CASES = (
    Changed("a light 7-joint arm, joint 5 held still through training and validation, moving in the test, "
            "10 s / 4 s / 6 s at 500 Hz, no dq", seven_joint_urdf, *logs(rate=500.0), held=5),
    Changed("PUMA 3 joints, the base joint behind an elastic belt (8 Hz, 5 % damping), the encoder on the motor, "
            "10 s / 4 s / 6 s at 1 kHz, no dq, a faster motion (0.5 Hz)", puma_urdf(3),
            *logs(rate=1000.0, motion_hz=0.5), belt=(1, 8.0), shaped=("sigmoid on tau1",)),
    Changed("PUMA 6 joints, torques logged as currents (unknown gains 0.3-1.8 A per N m, joint 2's sign flipped), "
            "10 s / 4 s / 6 s at 250 Hz, no dq", puma_urdf(6), *logs(),
            gains=(0.8, -0.5, 1.2, 1.8, 1.5, 0.3), said=r'"torque_signs": \{"joint2": -1\}',
            unsaid=r'offset from (its|the robot description\'s) zeros|"offsets"'),  # before h-zeros: joint 2 -38°
    Changed("PUMA 6 joints, a 2 kg payload picked up before the test (not in the training, nothing says so), "
            "10 s / 4 s / 6 s at 250 Hz, no dq", puma_urdf(6), *logs(), payload=2.0),
    # before h-payload2: after diagnose 1.9855 ± 0.0033 kg (4.3 standard deviations low; the diagnosis leaves the
    # truth's offset on tau2 out, its torque taken up by the bodies on the training motion); the model's covariance
    # now scaled by the error the record shows above its noise floor: 1.9855 ± 0.0102 kg
    Changed("PUMA 3 joints, the tool pressed on a table for 1 s of the training record (40 N up on the last "
            "frame), 10 s / 4 s / 6 s at 250 Hz, no dq", puma_urdf(3), *logs(), contact=40.0),
    Changed("PUMA 6 joints on a mobile base, level while trained, 2° off level in the test, 10 s / 4 s / 6 s at "
            "250 Hz, no dq", puma_urdf(6), *logs(), tilt=2.0),
)


@pytest.mark.parametrize("case", [pytest.param(case, id=case.name, marks=marks(case)) for case in CASES])
def test_the_defaults_run_and_predict_a_changed_robot_as_well_as_a_plain_fit(case, tmp_path):
    outcome = run_changed(case, tmp_path)
    print(f"\nreproduced validation error (relative): {outcome['reproduced']}; floor {outcome['floor'].round(5)}; "
          f"mse {({label: values.round(5).tolist() for label, values in outcome['mse'].items()})}")
    as_well_as_the_plain_fit(case.name, outcome, f"chosen {outcome['selections']}; ")
    for label, error in outcome["reproduced"].items():
        assert error < RELATIVE, (label, error)
    plain_class = ("viscous on", "coulomb on", "offset on")  # the truth's own laws; nothing else named
    named = [effect for effect in outcome["effects"]["diagnose"] if not effect.startswith(plain_class)]
    assert set(named) <= set(case.shaped), named
    said = json.loads((tmp_path / "default.json").read_text())["warnings"]
    if case.said:
        assert any(re.search(case.said, text) for text in said), said
    for label in ("default", "diagnose") if case.unsaid else ():
        warned = json.loads((tmp_path / f"{label}.json").read_text())["warnings"]
        assert not [text for text in warned if re.search(case.unsaid, text)], (label, warned)
    missed = said_changes(case, tmp_path)
    for label in ("default", "diagnose"):  # a still joint's declared friction left out and said, nowhere else
        left = json.loads((tmp_path / f"{label}.json").read_text()).get("not_determined", [])
        left_out = {item["parameter"] for item in left}  # diagnose declares viscous and offset, the rest candidates
        assert bool(left_out) == bool(case.held) and left_out <= {f"fv{case.held}", f"fc{case.held}"}, (label, left)
    assert tuple(missed) == case.estimate_missed, missed
    if missed:  # held as measured: a strict xfail by hand (the rest of the case asserted above)
        pytest.xfail(f"the change's estimate more than 3 standard deviations off the truth: {missed}")


def said_changes(case: Changed, folder: Path) -> dict[str, str]:
    """``oed predict`` on the test record after each verb says the payload or the tilt the test holds and nothing on
    the other cases (:mod:`estimation.identification.record_changes`); the verbs after which its estimate is more
    than three standard deviations off the truth, with the figures."""
    from oed.workflows.predict import predict

    expected = ["payload"] if case.payload else ["gravity"] if case.tilt else []
    missed = {}
    for label in ("default", "diagnose"):
        result = folder / f"{label}.json"
        if not result.is_file():
            continue
        changed = predict(model=result, data=[folder / "test.csv"]).to_dict()["changed"]
        said = [entry["change"] for entry in changed["said"]]
        assert said == expected, (label, changed["summary"])
        entry = changed["said"][0] if said else {}
        if case.payload:  # a point mass on joint 6's axis loads links 5 and 6 alike: both named, the estimate on 6
            assert entry["link"] == "joint6" and set(entry["link_candidates"]) <= {"joint5", "joint6"}, entry
        if case.payload and not (abs(entry["mass"] - case.payload) <= 3 * entry["mass_std"]
                                 and abs(entry["com"][2] - 0.1) <= 3 * entry["com_std"][2] + 1e-3):
            missed[label] = f"mass {entry['mass']:.4f} ± {entry['mass_std']:.2g} kg, z {entry['com'][2]:.4f} m"
        if case.tilt and not abs(entry["tilt_deg"] - case.tilt) <= 3 * entry["tilt_std_deg"]:
            missed[label] = f"tilt {entry['tilt_deg']:.3f} ± {entry['tilt_std_deg']:.2g}°"
    return missed


@pytest.mark.slow  # one oed identify (about a minute at load 15) and its oed predict
def test_a_payload_is_said_when_half_of_the_test_record_barely_moves_the_wrist(tmp_path, monkeypatch):
    """The 2 kg payload case drawn again (records of seeds 1111-1113, the draw h-payload2's twelve left unsaid): the
    test record's first half barely moves joints 4 and 6, and a payload fitted on it put −0.5 to −0.8 kg m² in the
    inertia the half does not determine, making tau5 on the other half 4.7 times worse (10 floors), so the third
    rule held a payload that lowers tau2's error 1800 floors. The cross-fits now leave at zero the directions a half
    determines no better than the family's scale: said on link 6, within three standard deviations."""
    from oed.workflows.predict import predict
    from tests.test_unseen_robot_kinds import quiet

    import tests.test_unseen_robot_changes as module

    case = next(case for case in CASES if case.payload)
    monkeypatch.setattr(module, "ROLES", (("train", 1111), ("validate", 1112), ("test", 1113)))
    urdf, _, files, _ = write_records(case, tmp_path)
    code, message = quiet(["identify", "--urdf", str(urdf), "--data", str(files["train"]), "--validate",
                           str(files["validate"]), "--friction", FRICTION, "--out", str(tmp_path / "default.json")])
    assert code == 0, message
    changed = predict(model=tmp_path / "default.json", data=[files["test"]]).to_dict()["changed"]
    assert [entry["change"] for entry in changed["said"]] == ["payload"], changed["summary"]
    entry = changed["said"][0]
    assert entry["link"] == "joint6" and set(entry["link_candidates"]) <= {"joint5", "joint6"}, entry
    assert abs(entry["mass"] - case.payload) <= 3 * entry["mass_std"], (entry["mass"], entry["mass_std"])
    assert max(entry["cross_fitted_ratio"].values()) <= 1.05, entry["cross_fitted_ratio"]


def test_a_still_joints_unexcited_columns_are_left_out_and_nothing_else():
    """The error of an all-zero column names its parameters as unexcited; the per-joint friction (and armature) of
    that joint is left out of its effect, the other joints keep theirs; a rigid-body parameter, or a rank
    deficiency that is not an all-zero column, leaves the error standing (``None``)."""
    from estimation.estimators import IdentificationProblem, IdentifiabilityError, LeastSquares
    from estimation.identification.undetermined import left_out_unexcited, not_determined

    generator = np.random.default_rng(0)
    Y = generator.normal(size=(50, 2, 3))
    Y[:, :, 1] = 0.0
    problem = IdentificationProblem(Y, generator.normal(size=(50, 2)), ("tau1", "tau2"), ("a", "fv2", "b"),
                                    ("a", "fv2", "b"))
    with pytest.raises(IdentifiabilityError) as caught:
        LeastSquares().fit(problem)
    assert caught.value.unexcited and caught.value.parameters == ("fv2",)
    model = build_model(load_robot("puma560", joints=3), "internal", f"{FRICTION},armature")
    effects, left = left_out_unexcited(model, ("fv2", "fc2", "Ia2"))
    assert [item.parameter for item in left] == ["fv2", "fc2", "Ia2"]
    kept = build_model(model.robot, "internal", effects).parameter_names
    assert {"fv1", "fv3", "fc1", "fc3", "off2", "Ia1", "Ia3"} <= set(kept) and not {"fv2", "fc2", "Ia2"} & set(kept)
    assert left_out_unexcited(model, ("fv2", "m3")) is None
    assert not_determined(model, IdentifiabilityError("rank deficient", ("fv2", "fc2"))) is None
    assert not_determined(model, IdentifiabilityError("zero", ("fv2",), unexcited=True))[1][0].parameter == "fv2"


@pytest.mark.slow
def test_a_still_joints_friction_is_left_out_alike_in_memory_and_streamed(tmp_path):
    """The 7-joint arm of the first case, joint 5 held still in the training and validation records: `oed identify`
    in memory and streamed (``--chunk-size``) both go on without fv5 and fc5 (and the armature candidate without
    Ia5), say it, and report the same validation errors (relative 1e-9)."""
    from tests.test_unseen_robot_kinds import quiet

    urdf, _, files, _ = write_records(CASES[0], tmp_path)
    documents = {}
    for label, more in (("memory", []), ("streamed", ["--chunk-size", "1000"])):
        out = tmp_path / f"{label}.json"
        code, message = quiet(["identify", "--urdf", str(urdf), "--data", str(files["train"]), "--validate",
                               str(files["validate"]), "--friction", FRICTION, *more, "--out", str(out)])
        assert code == 0, message
        documents[label] = json.loads(out.read_text())
    for document in documents.values():
        assert [item["parameter"] for item in document["not_determined"]] == ["fv5", "fc5"]
        assert sum("(fv5) is zero on every training sample" in text for text in document["warnings"]) == 1
    memory, streamed = (documents[label]["validation"]["mse"] for label in ("memory", "streamed"))
    assert all(abs(streamed[channel] - value) <= 1e-9 * value for channel, value in memory.items()), (memory, streamed)
