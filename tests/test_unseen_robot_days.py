"""Robots and logs the project has not seen, as a new user brings them on another day (issue 34), beside the other
``tests/test_unseen_robot*`` files (h-unseen15):

- friction that differs by direction: each joint's viscous friction 40 % stronger turning one way than the other
  (a term ``c |dq|`` beside ``fv dq``) and its Coulomb level ±30 % by direction: the Coulomb asymmetry is an
  offset of the plain class, the viscous one the diagnosis's family ``viscous:direction`` (h-dirfriction), outside
  the plain class ``oed identify`` is told;
- a description exported for kinematics only: every link's mass, centre of mass and inertia zero, so the
  consistent candidate's prior, the description's bodies, is no body at all;
- an event-triggered logger: a row written when any joint has moved 1 mrad since the last row, or 10 ms have passed
  (a 1 kHz sampler: bursts of 1 kHz while the arm moves fast, 100 Hz while it is slow);
- records of two days: training on the first, the validation and the test on the second, after the shoulder's
  motor was changed and the joint re-mastered 2° off its old zero;
- a long arm whose shoulder and elbow sag under gravity: the encoders on the motors, the links behind gears of a
  finite stiffness, the logged angles the motors' (the links' plus their load over the stiffness: 0.5° at the
  largest load), a truth outside every candidate family;
- training and validation on slow motions only (a fundamental of 0.08 Hz), the test fast point-to-point moves
  (70 % of the speed limits).

No data are copied; every record is simulated as :mod:`tests.test_unseen_robot_labs` does (the plain fit's model
class, :func:`tests.test_unseen_robots.truth`, each case's reality, white torque noise of 2 % of each channel's
spread). Each case runs the default ``oed identify`` (told the plain fit's model class) and ``oed diagnose`` (its
own defaults), then ``oed predict`` on the test record no choice saw (another kind of motion than the training's),
against the plain Pinocchio least-squares fit of ``benchmarks/bench_real_robots.py`` on the same recorded samples
(it reads the records a user reads, and the description the simulation used): per joint within 1.3x, in total at
most 1.0x, each figure allowed its noise floor's sampling spread; ``oed predict`` on the validation record
reproduces the validation error each verb reported (relative 1e-6); no verb names an effect the truth does not
hold."""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tests.test_one_answer_audit import RELATIVE
from tests.test_unseen_robot_benches import marks  # a Day has its Lab as a Bench does
from tests.test_unseen_robot_kinds import as_well_as_the_plain_fit, named_law, ur10e
from tests.test_unseen_robot_labs import Lab, puma, verbs_against_the_plain_fit, write_records
from tests.test_unseen_robots import Log

#: what a logger does to one role's record: ``(role, table, record) -> (table, record)``, the file and the plain
#: fit's record alike (the plain fit reads what the user reads)
Logger = Callable[[str, pd.DataFrame, object], tuple[pd.DataFrame, object]]


@dataclass(frozen=True)
class Day:
    """One case: the lab's records, what the logger does to them, the description as the user hands it over, and
    the effects a verb may name (the truth's own; any other is a false effect)."""

    lab: Lab
    logger: Logger | None = None
    described: Callable[[str], str] | None = None  # the URDF the verbs are given (the plain fit's the simulation's)
    may_name: tuple[str, ...] = ("coulomb", "viscous", "offset")

    @property
    def name(self) -> str:
        return self.lab.name


def run_day(day: Day, folder: Path) -> dict:
    """Write the records (:func:`tests.test_unseen_robot_labs.write_records`), let the logger rewrite each, hand
    over the description, run the plain fit and the verbs
    (:func:`tests.test_unseen_robot_labs.verbs_against_the_plain_fit`)."""
    from benchmarks.bench_real_robots import PlainFit

    urdf, records, files, spread = write_records(day.lab, folder)
    if day.logger is not None:
        for role, path in files.items():
            table, records[role] = day.logger(role, pd.read_csv(path), records[role])
            table.to_csv(path, index=False, float_format="%.10g")
    simulated = folder / "simulated.urdf"
    simulated.write_text(urdf.read_text())
    if day.described is not None:
        urdf.write_text(day.described(urdf.read_text()))
    plain = PlainFit(["--urdf", str(simulated)])
    rate = min(log.rate_hz for log in (day.lab.train, day.lab.validate, day.lab.test))
    cutoff, plain_theta = plain.fit(records["train"], records["validate"], rate_hz=rate)
    predicted_plain, kept = plain.predict(records["test"], cutoff, plain_theta)
    outcome = verbs_against_the_plain_fit(urdf, files, records["test"], kept, predicted_plain, folder)
    return {**outcome, "cutoff": cutoff, "floor": (0.02 * spread) ** 2}


def checked(name: str, outcome: dict, may_name: tuple[str, ...] = ("coulomb", "viscous", "offset"),
            verbs: tuple[str, ...] = ("default", "diagnose")) -> None:
    """Each of ``verbs`` within the plain fit's margins, ``oed predict`` reproducing each reported validation error,
    no effect named beyond ``may_name`` (:func:`tests.test_unseen_robot_kinds.named_law`)."""
    print(f"\nreproduced validation error (relative): {outcome['reproduced']}")
    as_well_as_the_plain_fit(name, outcome, f"chosen {outcome['selections']}; ", verbs)
    for label, error in outcome["reproduced"].items():
        assert label not in verbs or error < RELATIVE, (label, error)
    for label, named in outcome["effects"].items():
        false = [effect for effect in named if named_law(effect) not in may_name]
        assert not false, (label, false)


def judged(day: Day, folder: Path) -> None:
    checked(day.name, run_day(day, folder), day.may_name)


def by_direction(q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Friction that differs by direction, beyond the truth's symmetric ``fv dq + fc sign(dq)``: a viscous term
    ``c_j |dq_j|`` (``c`` 1 to 3 N m s/rad along the joints: with ``fv`` 2 to 10, one direction's viscous friction
    up to 40 % above the other's) and a Coulomb term ``a_j`` on positive speeds only (0.6 to 1.8 N m)."""
    n = q.shape[1]
    viscous = np.linspace(1.0, 3.0, n)
    coulomb = np.linspace(0.6, 1.8, n)
    return viscous * np.abs(dq) + coulomb * (dq > 0)


def kinematics_only(text: str) -> str:
    """The description as a kinematics-only export writes it: every link's mass, centre of mass and inertia zero."""
    text = re.sub(r'<mass value="[^"]*"\s*/>', '<mass value="0" />', text)
    text = re.sub(r'(<inertial>\s*<origin xyz=")[^"]*(")', r"\g<1>0 0 0\2", text)
    return re.sub(r"<inertia [^>]*/>", '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0" />', text)


def event_triggered(threshold: float = 1e-3, heartbeat: float = 0.010) -> Logger:
    """A logger writing a row when any joint has moved ``threshold`` (rad) since the last row written, or
    ``heartbeat`` seconds have passed: from a 1 kHz sampler, bursts at its rate while the arm moves fast, the
    heartbeat's rate while it is slow."""

    def logger(role: str, table: pd.DataFrame, record) -> tuple[pd.DataFrame, object]:
        del role
        t, q = record.t, record.q
        rows, last = [0], 0
        for k in range(1, t.shape[0]):
            if np.max(np.abs(q[k] - q[last])) >= threshold or t[k] - t[last] >= heartbeat - 1e-9:
                rows.append(k)
                last = k
        rows = np.asarray(rows)
        kept = dataclasses.replace(record, t=record.t[rows], q=record.q[rows], tau=record.tau[rows],
                                   dq=None if record.dq is None else record.dq[rows])
        return table.iloc[rows].reset_index(drop=True), kept

    return logger


def remastered(joint: int = 2, degrees: float = 2.0) -> Logger:
    """The second day's records (validation and test): joint ``joint``'s encoder re-mastered ``degrees`` off the
    first day's zero (its motor changed), so the logged angle reads ``q + δ``; the training record the first
    day's."""

    def logger(role: str, table: pd.DataFrame, record) -> tuple[pd.DataFrame, object]:
        if role == "train":
            return table, record
        shift = np.radians(degrees)
        q = record.q.copy()
        q[:, joint - 1] += shift
        return table.assign(**{f"q{joint}": table[f"q{joint}"] + shift}), dataclasses.replace(record, q=q)

    return logger


def sagging(joints: tuple[int, ...] = (2, 3), degrees: float = 0.5) -> Logger:
    """The motors' encoders of a long arm whose links sag behind gears of finite stiffness: the logged angle of
    each of ``joints`` is the link's plus its torque over the stiffness ``k_j`` (the torque the gear carries),
    ``k_j`` such that the channel's largest torque in the training record bends it ``degrees``. The
    stiffness is the robot's, so each record's sag is its torque over the same ``k``."""
    stiffness: dict[int, float] = {}

    def logger(role: str, table: pd.DataFrame, record) -> tuple[pd.DataFrame, object]:
        q = record.q.copy()
        out = table.copy()
        for joint in joints:
            torque = record.tau[:, joint - 1]
            if joint not in stiffness:  # the training record comes first
                stiffness[joint] = float(np.max(np.abs(torque))) / np.radians(degrees)
            sag = torque / stiffness[joint]
            q[:, joint - 1] += sag
            out[f"q{joint}"] = table[f"q{joint}"].to_numpy() + sag
        return out, dataclasses.replace(record, q=q)

    return logger


def logs(seconds: tuple[float, float, float] = (10.0, 4.0, 8.0), rate: float = 250.0, velocity: bool = False,
         **more) -> tuple[Log, ...]:
    return tuple(Log(duration, rate, velocity=velocity, **more) for duration in seconds)


DAYS = (
    Day(Lab("UR10e-like, the URDF exported for kinematics only (every mass and inertia zero), 10 s / 4 s / 8 s at "
            "500 Hz, logged dq, point-to-point test", ur10e, *logs(rate=500.0, velocity=True, motion_hz=0.1),
            test_motion="point-to-point", slow=True),
        described=kinematics_only),
    Day(Lab("PUMA 6 joints, an event-triggered logger (a row per 1 mrad moved or per 10 ms: 100-1000 Hz), "
            "10 s / 4 s / 8 s, no dq, point-to-point test", puma(6), *logs(rate=1000.0),
            test_motion="point-to-point", slow=True),
        logger=event_triggered()),
    Day(Lab("PUMA 6 joints, two days: the shoulder re-mastered 2 degrees off between training and the "
            "validation and test, 10 s / 4 s / 8 s at 250 Hz, no dq, point-to-point test", puma(6), *logs(),
            test_motion="point-to-point", slow=True),
        logger=remastered()),
    Day(Lab("UR10e-like, shoulder and elbow sagging behind stiff gears (0.5 degrees at the largest load, the "
            "encoders on the motors), 10 s / 4 s / 8 s at 500 Hz, logged dq, point-to-point test", ur10e,
            *logs(rate=500.0, velocity=True, motion_hz=0.1), test_motion="point-to-point", slow=True,
            xfail="identify 1.034 in total (joint 2 1.146x: its wls 0.689 against the plain fit's 0.602 N m "
                  "squared, its own ols 0.568, the wls chosen on validation 1.00 against 1.02); diagnose the same "
                  "since h-tie20, 1.034, joint 2 1.146x (until then 1.214, joint 2 1.88x: the offset on tau2 left "
                  "out, the plain law completed validating 1 against 1.002, within the 1 % band then kept by the "
                  "model with fewer laws; the lower score now decides); the sag (the "
                  "shoulder's torque over its stiffness read as angle) is outside every family; nothing false "
                  "named; measured at 4252663, the same at 6ee74d4. Traced (h-compliance, tests/compliance_trace.py): "
                  "the plain fit on the links' angles 0.879 of its own on the logged ones (joint 2 0.734); the "
                  "verbs on the records corrected by the stiffnesses a Gauss-Newton compliance law fits on the "
                  "plain class (17256 and 8394 N m/rad, true 17263 and 8099) 0.887 and 0.885, joint 2 0.74x; but "
                  "the validation record tells the shoulder's law from none by 1.6 standard errors only, and the "
                  "elbow's alone (k 7031) predicts the test at 1.16 and 1.25, joint 2 1.8x and 2.2x; the joints' laws as one decision "
                  "(2 and 3 together, 2.9 standard errors) 0.891 on the plain class; identify --method ols 0.99. "
                  "h-sag2: paired on the validation blocks (model_selection.weighting_difference), wls leads ols "
                  "by 0.0218 (standard error 0.0043, 5.0 of them): the Fourier validation record really prefers "
                  "wls, it cannot see the sag the point-to-point test pays for, so no rule on that record's "
                  "sampling error takes ols; identify 1.034 and diagnose 1.214 unchanged there (diagnose 1.034 since h-tie20)"),
        logger=sagging()),
    Day(Lab("PUMA 6 joints, slow training and validation (0.08 Hz), a fast point-to-point test, 12 s / 6 s / 8 s "
            "at 250 Hz, no dq", puma(6), Log(12.0, 250.0, velocity=False, motion_hz=0.08),
            Log(6.0, 250.0, velocity=False, motion_hz=0.08), Log(8.0, 250.0, velocity=False),
            test_motion="point-to-point", rest=0.2, slow=True)),
)


@pytest.mark.parametrize("day", [pytest.param(day, id=day.name, marks=marks(day)) for day in DAYS])
def test_the_defaults_run_and_predict_another_days_log_as_well_as_a_plain_fit(day, tmp_path):
    judged(day, tmp_path)


#: friction differing by direction: ``oed diagnose`` may name the viscous law's direction variant (the truth holds
#: it), never another family; ``oed identify`` is told the plain class, which cannot hold the ``c |dq|`` term
BY_DIRECTION = Day(Lab("PUMA 6 joints, friction differing by direction (viscous up to 40 % stronger one way, Coulomb "
                       "+-30 %), 10 s / 4 s / 8 s at 250 Hz, no dq, point-to-point test", puma(6), *logs(),
                       extra=by_direction, test_motion="point-to-point", slow=True),
                   may_name=("coulomb", "viscous", "offset", "viscous:direction"))


@pytest.fixture(scope="module")
def by_direction_outcome(tmp_path_factory) -> dict:
    """One run of :data:`BY_DIRECTION` for both verbs' tests (each worker that runs one of them runs it once)."""
    return run_day(BY_DIRECTION, tmp_path_factory.mktemp("by_direction"))


@pytest.mark.slow
def test_diagnose_names_friction_by_direction_and_predicts_as_well_as_a_plain_fit(by_direction_outcome):
    """Friction differing by direction (:func:`by_direction`): ``oed diagnose`` on its defaults names the viscous
    slope differing by direction (``viscous:direction``) on the joints and nothing outside the truth (no armature),
    and predicts the point-to-point test within the plain fit's margins. Measured at 4252663, before the family
    existed: 1.166 in total, joint 2 4.18x the plain fit, an armature named on tau3."""
    checked(BY_DIRECTION.name, by_direction_outcome, BY_DIRECTION.may_name, verbs=("diagnose",))
    named = by_direction_outcome["effects"]["diagnose"]
    assert any(effect.startswith("viscous:direction on ") for effect in named), named


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="identify (told the plain class: viscous, coulomb, offset) 1.096 in total, "
                   "joint 2 3.48x the plain fit (16.0 against 4.60 N m squared; its floor 0.027: every plain-class fit "
                   "60-500x above the floors on this test). The c |dq| term is outside the class it is told; each of "
                   "identify's candidates predicts joint 2 worse than the plain fit on the test (ols 7.31, wls 23.8, "
                   "consistent 16.4 N m squared) while the validation record, a Fourier motion like the training, "
                   "scores them ols 14.2, wls 1.59, consistent 1.00 (the criterion): it cannot see how the unmodelled "
                   "term projects on the test's moves and rests; with --friction viscous,viscous:direction,coulomb,"
                   "offset the class holds the truth; measured at 4252663 and again on h-dirfriction")
def test_identify_told_the_plain_class_predicts_friction_by_direction_as_well_as_a_plain_fit(by_direction_outcome):
    """The same record, ``oed identify`` told the plain fit's model class."""
    checked(BY_DIRECTION.name, by_direction_outcome, BY_DIRECTION.may_name, verbs=("default",))


DUAL_ARM = """<?xml version="1.0"?>
<robot name="dual_arm">
  <link name="world"/>
  <joint name="stand" type="fixed"><origin xyz="0 0 0.9"/><parent link="world"/><child link="torso"/></joint>
  <link name="torso"><inertial><origin xyz="0 0 0.2"/><mass value="25"/><inertia ixx="1.0" ixy="0" ixz="0" iyy="1.0" iyz="0" izz="0.4"/></inertial></link>
  <joint name="left_j1" type="revolute"><origin xyz="0 0.25 0.4" rpy="-1.5708 0 0"/><axis xyz="0 0 1"/><parent link="torso"/><child link="left_shoulder"/>
    <limit lower="-2.8" upper="2.8" velocity="2.0" effort="150"/></joint>
  <link name="left_shoulder"><inertial><origin xyz="0 0.01 0.05"/><mass value="4"/><inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.015"/></inertial></link>
  <joint name="left_j2" type="revolute"><origin xyz="0 0 0.1"/><axis xyz="0 1 0"/><parent link="left_shoulder"/><child link="left_upper"/>
    <limit lower="-1.8" upper="1.8" velocity="2.0" effort="150"/></joint>
  <link name="left_upper"><inertial><origin xyz="0.15 0 0.01"/><mass value="3"/><inertia ixx="0.005" ixy="0" ixz="0.001" iyy="0.03" iyz="0" izz="0.03"/></inertial></link>
  <joint name="left_j3" type="revolute"><origin xyz="0.32 0 0"/><axis xyz="0 1 0"/><parent link="left_upper"/><child link="left_fore"/>
    <limit lower="-2.2" upper="2.2" velocity="2.5" effort="80"/></joint>
  <link name="left_fore"><inertial><origin xyz="0.13 0.005 0"/><mass value="2"/><inertia ixx="0.003" ixy="0" ixz="0" iyy="0.015" iyz="0" izz="0.015"/></inertial></link>
  <joint name="right_j1" type="revolute"><origin xyz="0 -0.25 0.4" rpy="1.5708 0 0"/><axis xyz="0 0 1"/><parent link="torso"/><child link="right_shoulder"/>
    <limit lower="-2.8" upper="2.8" velocity="2.0" effort="150"/></joint>
  <link name="right_shoulder"><inertial><origin xyz="0 -0.01 0.05"/><mass value="4.2"/><inertia ixx="0.021" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.016"/></inertial></link>
  <joint name="right_j2" type="revolute"><origin xyz="0 0 0.1"/><axis xyz="0 1 0"/><parent link="right_shoulder"/><child link="right_upper"/>
    <limit lower="-1.8" upper="1.8" velocity="2.0" effort="150"/></joint>
  <link name="right_upper"><inertial><origin xyz="0.15 0 -0.01"/><mass value="3.1"/><inertia ixx="0.005" ixy="0" ixz="-0.001" iyy="0.031" iyz="0" izz="0.03"/></inertial></link>
  <joint name="right_j3" type="revolute"><origin xyz="0.32 0 0"/><axis xyz="0 1 0"/><parent link="right_upper"/><child link="right_fore"/>
    <limit lower="-2.2" upper="2.2" velocity="2.5" effort="80"/></joint>
  <link name="right_fore"><inertial><origin xyz="0.13 -0.005 0"/><mass value="2.1"/><inertia ixx="0.003" ixy="0" ixz="0" iyy="0.016" iyz="0" izz="0.015"/></inertial></link>
</robot>
"""

#: the dual-arm robot's two chains from its fixed torso
ARMS = {"left": ("left_j1", "left_j2", "left_j3"), "right": ("right_j1", "right_j2", "right_j3")}


def arm(names: tuple[str, ...]) -> Callable[[], object]:
    """One chain of :data:`DUAL_ARM` (the other's joints locked: on a fixed torso they move nothing of this one)."""
    from dynamics.robots import load_robot
    from tests.test_unseen_robot_benches import written

    return lambda: load_robot(urdf=written(DUAL_ARM), joint_names=names)


def joint_state_export(tables: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Both arms' records in one table as a ROS ``JointState`` export writes it: ``t``, then
    ``<joint>_position`` and ``<joint>_effort`` of every joint of both arms."""
    out = pd.DataFrame({"t": next(iter(tables.values()))["t"]})
    for group, suffix in (("q", "position"), ("tau", "effort")):
        for side, table in tables.items():
            for index, name in enumerate(ARMS[side]):
                out[f"{name}_{suffix}"] = table[f"{group}{index + 1}"].to_numpy()
    return out


def both_arms_written(folder: Path, export: Callable[[dict[str, pd.DataFrame]], pd.DataFrame]) -> tuple:
    """Each arm's lab records (training and validation Fourier motions, the test point-to-point moves: 10 s / 4 s /
    8 s at 250 Hz, no dq) written under ``folder/<side>``, and both arms' records in one table a role as ``export``
    writes it: ``(description, files, written)``, ``written[side]`` what :func:`write_records` returned."""
    tables, written = {}, {}
    for side, names in ARMS.items():
        lab = Lab(f"the dual arm's {side} arm", arm(names), *logs(), test_motion="point-to-point")
        (folder / side).mkdir()
        written[side] = write_records(lab, folder / side)
        tables[side] = {role: pd.read_csv(path) for role, path in written[side][2].items()}
    description = folder / "dual_arm.urdf"
    description.write_text(DUAL_ARM, encoding="utf-8")
    files = {}
    for role in ("train", "validate", "test"):
        files[role] = folder / f"{role}.csv"
        export({side: tables[side][role] for side in ARMS}).to_csv(files[role], index=False, float_format="%.10g")
    return description, files, written


def plain_fit_of(urdf: Path, records: dict) -> tuple:
    """The plain fit of one arm (its own URDF and records): ``(cutoff, kept, predicted)`` on the test record."""
    from benchmarks.bench_real_robots import PlainFit

    plain = PlainFit(["--urdf", str(urdf)])
    cutoff, plain_theta = plain.fit(records["train"], records["validate"], rate_hz=250.0)
    predicted_plain, kept = plain.predict(records["test"], cutoff, plain_theta)
    return cutoff, kept, predicted_plain


@pytest.mark.slow
def test_a_dual_arms_log_exits_naming_each_arm_and_each_arm_predicts_as_well_as_a_plain_fit(tmp_path):
    """A dual-arm robot (two 3-joint arms on a fixed torso, :data:`DUAL_ARM`), one log holding both arms' joints
    named as a ``JointState`` export names them; training and validation Fourier motions, the test point-to-point
    moves (10 s / 4 s / 8 s at 250 Hz, no dq). The default ``oed identify`` exits (code 2, no traceback) naming
    each arm's ``--joint-names`` (measured at 4252663: it named ``--joint-names`` followed by nothing, "the chain
    from the base to the branch" being empty when the branch is the base); with each arm's option, ``oed identify``
    and ``oed diagnose`` then ``oed predict`` do as well as the plain fit of that arm on the test record, and
    ``oed predict`` reproduces each reported validation error."""
    from tests.test_unseen_robot_kinds import quiet

    description, files, written_arms = both_arms_written(tmp_path, joint_state_export)
    code, message = quiet(["identify", "--urdf", str(description), "--data", str(files["train"]), "--validate",
                           str(files["validate"]), "--out", str(tmp_path / "refused.json")])
    assert code == 2 and "Traceback" not in message, message
    for names in ARMS.values():
        assert f"--joint-names {','.join(names)}" in message, message
    for side, names in ARMS.items():
        urdf, records, _, spread = written_arms[side]
        cutoff, kept, predicted_plain = plain_fit_of(urdf, records)
        outcome = verbs_against_the_plain_fit(description, files, records["test"], kept, predicted_plain,
                                              tmp_path / side, options=("--joint-names", ",".join(names)))
        checked(f"the dual arm's {side} arm", {**outcome, "cutoff": cutoff, "floor": (0.02 * spread) ** 2})


def numbered_export(tables: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Both arms' records in one table numbering the description's joints in its order: ``t``, then ``q1..q6``
    (the left arm's three, then the right arm's), ``tau1..tau6`` and the other groups alike."""
    out = pd.DataFrame({"t": next(iter(tables.values()))["t"]})
    for group in ("q", "dq", "tau"):
        for offset, side in enumerate(ARMS):
            for index in range(1, len(ARMS[side]) + 1):
                if f"{group}{index}" in tables[side]:
                    out[f"{group}{3 * offset + index}"] = tables[side][f"{group}{index}"].to_numpy()
    return out


@pytest.mark.slow
def test_a_log_numbering_both_arms_predicts_each_arm_as_well_as_a_plain_fit(tmp_path):
    """The dual arm's records (:func:`test_a_dual_arms_log_exits_naming_each_arm_and_each_arm_predicts_as_well_as_a_plain_fit`'s
    motions) in one table numbering both arms' joints in the description's order (``q1..q6``, ``tau1..tau6``):
    each arm's ``--joint-names`` alone reads its own columns; ``oed identify`` and ``oed diagnose`` then ``oed
    predict`` do as well as the plain fit of that arm on the test record, and ``oed predict`` reproduces each
    reported validation error. At 6ee74d4 the left arm exited on every verb ("column(s) q4, q5, q6, tau4, tau5,
    tau6 beyond the robot's 3 joint(s)"), the right arm needed ``--columns q1=q4,...``."""
    description, files, written_arms = both_arms_written(tmp_path, numbered_export)
    for side, names in ARMS.items():
        urdf, records, _, spread = written_arms[side]
        cutoff, kept, predicted_plain = plain_fit_of(urdf, records)
        outcome = verbs_against_the_plain_fit(description, files, records["test"], kept, predicted_plain,
                                              tmp_path / side, options=("--joint-names", ",".join(names)),
                                              reading=())
        checked(f"the dual arm's {side} arm, a log numbering both arms", {**outcome, "cutoff": cutoff,
                                                                          "floor": (0.02 * spread) ** 2})


@pytest.mark.slow
def test_a_log_numbering_both_arms_is_streamed_as_memory_reads_it(tmp_path):
    """The right arm of a log numbering both arms' joints (``q4..q6``, ``tau4..tau6`` its own), ``oed identify`` in
    memory and streamed (``--chunk-size 500``): the same columns read, the parameters and the training error equal
    (relative 1e-9). At 6ee74d4 both paths exited naming the columns beyond the robot's 3 joints."""
    import json

    from tests.test_unseen_robot_kinds import quiet

    t = np.arange(0.0, 8.0, 0.004)
    rng = np.random.default_rng(3)
    table = pd.DataFrame({"t": t} | {f"q{j}": 0.5 * np.sin(0.6 * np.pi * j * t + j) + 0.2 * np.sin(1.4 * np.pi * j * t)
                                     for j in range(1, 7)}
                         | {f"tau{j}": np.cos(0.8 * np.pi * t + j) + 0.01 * rng.standard_normal(t.size)
                            for j in range(1, 7)})
    table.to_csv(tmp_path / "both.csv", index=False)
    (tmp_path / "dual_arm.urdf").write_text(DUAL_ARM, encoding="utf-8")
    results = {}
    for label, more in (("memory", ()), ("streamed", ("--chunk-size", "500"))):
        code, message = quiet(["identify", "--urdf", str(tmp_path / "dual_arm.urdf"), "--joint-names",
                               ",".join(ARMS["right"]), "--data", str(tmp_path / "both.csv"), "--friction", "viscous",
                               *more, "--out", str(tmp_path / f"{label}.json")])
        assert code == 0, message
        results[label] = json.loads((tmp_path / f"{label}.json").read_text())
    assert [results[label]["identification_path"] for label in results] == ["in-memory", "streamed"]
    values = {label: np.array([entry["value"] for entry in result["parameters"]]) for label, result in results.items()}
    assert np.allclose(values["streamed"], values["memory"], rtol=1e-9, atol=1e-9 * np.abs(values["memory"]).max())
    for channel, mse in results["memory"]["train"]["mse"].items():
        assert results["streamed"]["train"]["mse"][channel] == pytest.approx(mse, rel=1e-9)


def test_a_dual_arms_description_names_each_arm_whatever_the_log_holds():
    """The dual-arm description read without joint names names each arm's ``--joint-names``: read as a serial
    chain (a log whose columns name the joints), for a log numbering all six joints (no chain of six from the
    base), and for one of three (two chains fit). At 4252663 the first named ``--joint-names`` followed by
    nothing and the second no chain at all."""
    from dynamics.errors import RobotDescriptionError
    from dynamics.robots import load_robot
    from dynamics.urdf import logged_chain
    from tests.test_unseen_robot_benches import written

    path = written(DUAL_ARM)
    said = [f"--joint-names {','.join(names)}" for names in ARMS.values()]
    for read in (lambda: load_robot(urdf=path), lambda: logged_chain(path, 6)):
        with pytest.raises(RobotDescriptionError) as raised:
            read()
        assert all(option in str(raised.value) for option in said), str(raised.value)
        assert "--joint-names )" not in str(raised.value)
    with pytest.raises(RobotDescriptionError, match="2 chains of 3 joint") as raised:
        logged_chain(path, 3)
    assert all(",".join(names) in str(raised.value) for names in ARMS.values()), str(raised.value)
    assert load_robot(urdf=path, joint_names=ARMS["right"]).n_joints == 3


def test_a_log_numbering_both_arms_is_read_for_each_arm_by_its_names(tmp_path):
    """A dual-arm log whose columns number all six joints in the description's order (``q1..q6``, ``tau1..tau6``):
    each arm read with its ``--joint-names``, its own columns (the left arm's ``q1..q3``, the right arm's
    ``q4..q6``), the other arm's left out and said (on a fixed torso its motion moves nothing of this one). At
    4252663 the left arm could not be read with any option: "column(s) q4, q5, q6, tau4, tau5, tau6 beyond the
    robot's 3 joint(s)" (the right arm read with ``--columns q1=q4,...``, which still reads as before). A chain
    whose other joints it carries (a PUMA's first three of six) keeps that error."""
    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from dynamics.urdf_export import robot_urdf
    from estimation.data.loading import JointCountError
    from estimation.data.log_formats import DescriptionOrderWarning, LogSource
    from estimation.data.records import read_measurements
    from tests.test_unseen_robot_benches import written

    t = np.arange(0.0, 2.0, 0.004)
    table = pd.DataFrame({"t": t} | {f"q{j}": 0.3 * np.sin(2 * np.pi * 0.4 * t + j) for j in range(1, 7)}
                         | {f"tau{j}": np.cos(2 * np.pi * 0.4 * t + j) for j in range(1, 7)})
    table.to_csv(tmp_path / "both_arms.csv", index=False)
    description = written(DUAL_ARM)
    for side, columns in (("left", ["tau1", "tau2", "tau3"]), ("right", ["tau4", "tau5", "tau6"])):
        model = build_model(load_robot(urdf=description, joint_names=ARMS[side]), "internal", "viscous")
        with pytest.warns(DescriptionOrderWarning, match=r"number the description's 6 joints in its order.*left "
                          r"out \(the joints (right|left)_j1"):
            read = read_measurements(tmp_path / "both_arms.csv", model=model)
        assert np.array_equal(read.as_recorded.tau, table[columns].to_numpy())
        assert np.array_equal(read.as_recorded.q, table[[column.replace("tau", "q") for column in columns]].to_numpy())
    mapped = LogSource(tmp_path / "both_arms.csv", columns={"q1": "q4", "q2": "q5", "q3": "q6", "tau1": "tau4",
                                                           "tau2": "tau5", "tau3": "tau6"})
    model = build_model(load_robot(urdf=description, joint_names=ARMS["right"]), "internal", "viscous")
    assert np.array_equal(read_measurements(mapped, model=model).as_recorded.tau, table[["tau4", "tau5", "tau6"]].to_numpy())
    puma = tmp_path / "puma.urdf"
    puma.write_text(robot_urdf(load_robot("puma560", joints=6)))
    first_three = load_robot(urdf=puma, joint_names=load_robot("puma560", joints=6).joint_names[:3])
    with pytest.raises(JointCountError, match="beyond the robot's 3 joint"):
        read_measurements(tmp_path / "both_arms.csv", model=build_model(first_three, "internal", "viscous"))


def test_an_mjcf_dual_arms_numbered_log_is_read_for_each_arm(tmp_path):
    """The dual arm as MuJoCo writes it from the URDF (MuJoCo 4's own import and ``mj_saveLastXML``: the torso
    fused into the world) and a log numbering its six joints in MuJoCo's ``qpos`` order: each arm read by its
    ``--joint-names`` from its own columns, as with the URDF. At 6ee74d4: the columns beyond the robot's 3 joints."""
    import mujoco

    from dynamics.mjcf import robot_from_mjcf
    from dynamics.models import build_model
    from estimation.data.log_formats import DescriptionOrderWarning
    from estimation.data.records import read_measurements

    (tmp_path / "dual_arm.urdf").write_text(DUAL_ARM, encoding="utf-8")
    mujoco.mj_saveLastXML(str(tmp_path / "dual_arm.xml"),
                          mujoco.MjModel.from_xml_path(str(tmp_path / "dual_arm.urdf")))
    t = np.arange(0.0, 2.0, 0.004)
    table = pd.DataFrame({"t": t} | {f"q{j}": 0.3 * np.sin(2 * np.pi * 0.4 * t + j) for j in range(1, 7)}
                         | {f"tau{j}": np.cos(2 * np.pi * 0.4 * t + j) for j in range(1, 7)})
    table.to_csv(tmp_path / "both_arms.csv", index=False)
    for side, columns in (("left", ["tau1", "tau2", "tau3"]), ("right", ["tau4", "tau5", "tau6"])):
        robot = robot_from_mjcf(tmp_path / "dual_arm.xml", joint_names=ARMS[side])
        with pytest.warns(DescriptionOrderWarning):
            read = read_measurements(tmp_path / "both_arms.csv", model=build_model(robot, "internal", "viscous"))
        assert np.array_equal(read.as_recorded.tau, table[columns].to_numpy())


@pytest.mark.parametrize("leftover", ["expression", "macro", "unbound prefix"])
def test_a_description_with_xacro_leftovers_is_refused_naming_xacro(leftover, tmp_path):
    """A description handed over before xacro expanded it: an expression left in a number (``${pi/2}``), xacro
    elements in a file declaring xacro's namespace, or the same without the declaration. Each is refused naming
    xacro and the command that expands it. At 4252663 the first was refused as "not three finite numbers" (xacro
    unnamed), the third as XML not well-formed, and the second read without a word, the elements inside its macro
    (an arm's links and joints, where a macro holds them) left out."""
    from dynamics.errors import RobotDescriptionError
    from dynamics.robots import load_robot

    if leftover == "expression":
        text = DUAL_ARM.replace('rpy="-1.5708 0 0"', 'rpy="-${pi/2} 0 0"')
    else:
        declared = ' xmlns:xacro="http://www.ros.org/wiki/xacro"' if leftover == "macro" else ""
        text = DUAL_ARM.replace('<robot name="dual_arm">', f'<robot name="dual_arm"{declared}>\n'
                                '  <xacro:property name="reach" value="0.32"/>\n'
                                '  <xacro:macro name="finger" params="side"><link name="${side}_finger"/></xacro:macro>')
    path = tmp_path / "dual_arm.urdf"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(RobotDescriptionError, match=r"a xacro file, not yet expanded.*xacro robot\.urdf\.xacro"):
        load_robot(urdf=path, joint_names=ARMS["left"])
    path.write_text(DUAL_ARM.replace('<robot name="dual_arm">',
                                     '<robot name="dual_arm" xmlns:xacro="http://www.ros.org/wiki/xacro">'))
    assert load_robot(urdf=path, joint_names=ARMS["left"]).n_joints == 3  # the declaration alone is no leftover


def in_millimetres(text: str) -> str:
    """The description as a CAD export in millimetres writes it: every ``<origin xyz>`` times 1000 (the masses and
    inertias left in SI, as the exporter's other settings had them)."""
    return re.sub(r'xyz="([^"]*)"', lambda found: 'xyz="' + " ".join(repr(1e3 * float(value))
                                                                     for value in found.group(1).split()) + '"', text)


def test_a_description_in_millimetres_is_refused_naming_the_unit(tmp_path):
    """The PUMA's description with its lengths in millimetres: ``oed identify`` exits (code 2, no traceback) naming
    metres and the factor. Measured at 4252663 on a PUMA 6 log (10 s / 4 s / 8 s at 250 Hz, point-to-point test):
    read without a word, identify predicted the test 152x worse than the plain fit on the description in metres
    (joint 2 797x), diagnose 94x, naming a ripple on tau2 and tau3 that the truth does not hold. The description in
    metres reads as before."""
    from dynamics.robots import load_robot
    from dynamics.urdf_export import robot_urdf
    from tests.test_unseen_robot_kinds import quiet

    text = robot_urdf(load_robot("puma560", joints=6))
    metres, millimetres = tmp_path / "puma.urdf", tmp_path / "puma_mm.urdf"
    metres.write_text(text)
    millimetres.write_text(in_millimetres(text))
    assert load_robot(urdf=metres).n_joints == 6
    code, message = quiet(["identify", "--urdf", str(millimetres), "--data", str(tmp_path / "absent.csv"), "--out",
                           str(tmp_path / "result.json")])
    assert code == 2 and "Traceback" not in message, message
    assert "lengths are metres" in message and "millimetres" in message and "1000" in message, message
