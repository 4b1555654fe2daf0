"""Rigs, tools and controllers the project has not seen (issue 34), beside the other unseen-robot modules
(:mod:`tests.test_unseen_robots`, ``_kinds``, ``_realities``, ``_labs``, ``_logs``, ``_cells``, ``_mounts``), run by
the same verbs and plain fit (:func:`tests.test_unseen_robot_labs.verbs_against_the_plain_fit`) (h-unseen9):

- a six-joint arm on a linear track (a horizontal prismatic seventh axis under the arm, its carriage 60 kg), the
  URDF's root the track and a fixed joint between the carriage and the arm's base;
- a light 7-joint arm whose URDF has continuous joints (no limits: joints 1, 3, 5, 7, as a Kinova Gen3's) and
  massless end-effector and tool frames on fixed joints;
- a tool fixed to the flange that the URDF does not hold (2.5 kg, 8 cm out along the flange's axis and 3 cm aside),
  so the description's bodies, the consistent fit's prior, are wrong on the last link;
- a log whose torque is the motor torque minus the controller's gravity model (the description's bodies: what an
  arm in gravity-compensation mode reports), the description itself ±20 % off the truth;
- torques logged 8 ms after the positions (another bus, another controller cycle) on a 500 Hz log;
- a parallelogram arm (a palletiser's linkage: motor 3 turns the forearm's absolute angle ``q2 + q3``), positions
  and torques logged on the motor side, given through ``--transmission``, motor 3's own friction felt by joints 2
  and 3;
- encoders mastered 1.5° and -1° off the description's zeros on the shoulder and the elbow (below the 2° the
  joint-zero check names, :mod:`estimation.identification.joint_zeros`);
- training and validation on a slow motion (a fundamental of 0.05 Hz: gravity-dominated, the speeds a tenth of the
  limits), the test at the usual 0.2 Hz.

No data are copied; every record is simulated here: the plain fit's model class
(:func:`tests.test_unseen_robots.truth`, the description's bodies ±20 % in the URDF's own frames), plus each case's
reality, white torque noise of 2 % of each channel's spread. Each case runs the default ``oed identify`` (told the
plain fit's model class) and ``oed diagnose`` (its own defaults), then ``oed predict`` on a test record no choice
saw, against the plain Pinocchio least-squares fit of ``benchmarks/bench_real_robots.py`` (its cut-off chosen on
the validation record, given the same description and the joint-side records a user would have) on the same
recorded samples: per joint within 1.3x, in total at most 1.0x, each figure allowed its noise floor's sampling
spread; ``oed predict`` on the validation record reproduces the validation error each verb reported (relative
1e-6); ``oed diagnose`` names no effect the truth does not hold, and ``oed identify`` finds no other mount (every
rig stands on the floor)."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from dynamics.dh import DHLink, robot_from_dh
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.urdf_export import robot_urdf
from oed.fourier import random_fourier
from tests.test_one_answer_audit import RELATIVE
from tests.test_unseen_robot_kinds import as_well_as_the_plain_fit, cylinder, marks, plain_fit
from tests.test_unseen_robot_labs import verbs_against_the_plain_fit
from tests.test_unseen_robots import FRICTION, NOISE, Log, logged, times, truth

PI = np.pi

#: a linear track under the arm: the track's frame 0.4 m above the floor, a 60 kg carriage moving along x over
#: ±1.5 m at up to 1 m/s, the arm's base 0.1 m above the carriage on a fixed joint
TRACK = """<link name="track" />
  <joint name="rail" type="prismatic"><origin xyz="0 0 0.4" rpy="0 0 0" /><parent link="track" />
    <child link="carriage" /><axis xyz="1 0 0" /><limit lower="-1.5" upper="1.5" velocity="1.0" effort="5000" /></joint>
  <link name="carriage"><inertial><origin xyz="0 0 0.05" rpy="0 0 0" /><mass value="60" />
    <inertia ixx="1.5" ixy="0" ixz="0" iyy="2.5" iyz="0" izz="3.5" /></inertial></link>
  <joint name="carriage_to_base" type="fixed"><origin xyz="0 0 0.1" rpy="0 0 0" /><parent link="carriage" />
    <child link="base_link" /></joint>
  <link name="base_link" />"""

#: a tool on the flange, not in the URDF: mass (kg), centre of mass in the last link's frame (m), its own inertia
#: about the centre of mass (kg m², a 10 cm cube's)
TOOL = (2.5, (0.03, 0.0, 0.08), 2.5 * 0.1**2 / 6.0)

#: the effects of the plain class that ``oed diagnose`` finds beyond its declared viscous model (the truth holds them)
PLAIN = r"(coulomb|offset) on tau\d+"

#: the parallelogram arm's gear ratios (the PUMA 560's published ones); motor 3 turns with q2 + q3
RATIOS = np.array([62.61, 107.36, 53.69, 76.04, 71.92, 76.69])


def seven_joint_urdf() -> str:
    """A light 7-joint arm: the KUKA iiwa's published DH geometry (d1 0.34, d3 0.4, d5 0.4, d7 0.126 m; alternating
    ±90° twists), the Kinova Gen3's published actuator masses (1.377, 1.163, 1.163, 0.930, 0.678, 0.678, 0.364 kg),
    the inertias of solid cylinders of those masses; joints 1, 3, 5 and 7 continuous (no ``lower``/``upper``, as the
    Gen3's URDF), joints 2, 4, 6 within ±128.9°, ±147.8°, ±120.3°; a massless ``end_effector_link`` and
    ``tool_frame`` on fixed joints after the last link."""
    rows = ((0.0, -PI / 2, 0.34), (0.0, PI / 2, 0.0), (0.0, PI / 2, 0.4), (0.0, -PI / 2, 0.0), (0.0, -PI / 2, 0.4),
            (0.0, PI / 2, 0.0), (0.0, 0.0, 0.126))
    mass = (1.377, 1.163, 1.163, 0.930, 0.678, 0.678, 0.364)
    shape = ((0.3, 0.05, 1, (0.0, 0.06, 0.0)), (0.1, 0.05, 2, (0.0, -0.01, 0.02)), (0.35, 0.045, 1, (0.0, 0.08, 0.0)),
             (0.1, 0.045, 2, (0.0, 0.01, 0.02)), (0.3, 0.04, 1, (0.0, 0.07, 0.0)), (0.08, 0.04, 2, (0.0, 0.0, 0.01)),
             (0.06, 0.035, 2, (0.0, 0.0, -0.02)))
    limit = np.radians((180.0, 128.9, 180.0, 147.8, 180.0, 120.3, 180.0))
    velocity = (1.39, 1.39, 1.39, 1.39, 1.22, 1.22, 1.22)
    links = [DHLink(*rows[j], inertial=cylinder(mass[j], *shape[j][:3], shape[j][3]), lower=-limit[j],
                    upper=limit[j], velocity=velocity[j], effort=(39.0, 39.0, 39.0, 39.0, 9.0, 9.0, 9.0)[j])
             for j in range(7)]
    text = robot_urdf(robot_from_dh("seven_joint_arm", links))
    for joint in (1, 3, 5, 7):
        text = re.sub(rf'(<joint name="joint{joint}" type=")revolute(">(?:(?!</joint>).)*?<limit) lower="[^"]*" '
                      r'upper="[^"]*"', r"\1continuous\2", text, count=1, flags=re.DOTALL)
    dummies = ('  <joint name="end_effector" type="fixed"><origin xyz="0 0 0.06" rpy="0 0 0" />'
               '<parent link="joint7_link" /><child link="end_effector_link" /></joint>\n'
               '  <link name="end_effector_link" />\n'
               '  <joint name="tool" type="fixed"><origin xyz="0 0 0.12" rpy="0 0 0" />'
               '<parent link="end_effector_link" /><child link="tool_frame" /></joint>\n'
               '  <link name="tool_frame" />\n</robot>')
    return text.replace("</robot>", dummies, 1)


def puma_urdf(joints: int, on_track: bool = False) -> Callable[[], str]:
    """The PUMA 560's description (``joints`` joints) as a URDF, on a linear track when ``on_track``."""
    def text() -> str:
        written = robot_urdf(load_robot("puma560", joints=joints))
        return written.replace('<link name="base_link" />', TRACK, 1) if on_track else written
    return text


@dataclass(frozen=True)
class Rig:
    """One case: the description, the log of each role and what the lab's rig, controller and logger hold beyond
    the plain class."""

    name: str
    urdf: Callable[[], str]  # the description given to the verbs and the plain fit (the truth its bodies ±20 %)
    train: Log
    validate: Log
    test: Log
    tool: bool = False  # :data:`TOOL` on the flange, not in the URDF
    compensated: bool = False  # the logged torque: the motor torque minus the description's gravity torque
    delay: float = 0.0  # the torques' lag behind the positions (s)
    parallelogram: bool = False  # motor side, motor 3 turning with q2 + q3 (:func:`transmission_matrix`)
    mastering: tuple[float, ...] = ()  # each joint's encoder zero off the description's (rad): logged q = q + δ
    named: str = ""  # a pattern of the effects beyond the plain class that ``oed diagnose`` may name (the truth's)
    slow: bool = False
    xfail: str = ""


def transmission_matrix(n: int) -> np.ndarray:
    """``R`` with ``θ_m = R q``: the gear ratios, motor 3 turning with the forearm's absolute angle ``q2 + q3``."""
    matrix = np.diag(RATIOS[:n])
    matrix[2, 1] = RATIOS[2]
    return matrix


def with_tool(model, theta: np.ndarray) -> np.ndarray:
    """``theta`` with :data:`TOOL` added to the last link's standard parameters (parallel-axis theorem)."""
    mass, com, own = TOOL
    com = np.asarray(com)
    inertia = own * np.eye(3) + mass * (com @ com * np.eye(3) - np.outer(com, com))
    n = model.robot.n_joints
    names = list(model.parameter_names)
    added = {"m": mass, "mx": mass * com[0], "my": mass * com[1], "mz": mass * com[2], "Ixx": inertia[0, 0],
             "Ixy": inertia[0, 1], "Iyy": inertia[1, 1], "Ixz": inertia[0, 2], "Iyz": inertia[1, 2],
             "Izz": inertia[2, 2]}
    out = theta.copy()
    for name, value in added.items():
        out[names.index(f"{name}{n}")] += value
    return out


def motor_friction(dq: np.ndarray) -> np.ndarray:
    """Motor 3's own viscous and Coulomb friction (motor side ``2e-4 ω + 0.02 sign ω`` N m at ``ω = r3 (dq2 +
    dq3)``), felt by joints 2 and 3 alike (``Rᵀ τ_m``)."""
    speed = RATIOS[2] * (dq[:, 1] + dq[:, 2])
    motor = RATIOS[2] * (2e-4 * speed + 0.02 * np.sign(speed))
    out = np.zeros_like(dq)
    out[:, 1] = out[:, 2] = motor
    return out


def write_records(case: Rig, folder: Path) -> tuple[Path, dict, dict, np.ndarray, tuple[str, ...]]:
    """The description (and the transmission file) and the records of each role as the lab's logger writes them:
    ``(urdf, records, files, spread, options)``; the plain fit's records are joint side, as logged otherwise."""
    from benchmarks.bench_real_robots import Record

    urdf = folder / "robot.urdf"
    urdf.write_text(case.urdf())
    robot = load_robot(urdf=urdf)
    model = build_model(robot, "internal", FRICTION)
    theta = truth(model)
    if case.tool:
        theta = with_tool(model, theta)
    described = model.nominal_parameters()
    described[robot.standard_parameters.shape[0]:] = 0.0  # the controller's gravity model: the bodies only
    n = robot.n_joints
    lower, upper = np.asarray(robot.lower, float), np.asarray(robot.upper, float)
    limits = SimpleNamespace(n_joints=n, lower=np.where(np.isfinite(lower), lower, -PI),  # a continuous joint: a turn
                             upper=np.where(np.isfinite(upper), upper, PI),
                             velocity_limit=np.asarray(robot.velocity_limit, float))
    options: tuple[str, ...] = ()
    if case.parallelogram:
        path = folder / "transmission.json"
        path.write_text(json.dumps({"ratios": RATIOS[:n].tolist(), "couplings": {"3": {"2": float(RATIOS[2])}}}))
        options = ("--transmission", str(path))
    spread, records, files = None, {}, {}
    for role, log, seed in (("train", case.train, 11), ("validate", case.validate, 12), ("test", case.test, 13)):
        generator = np.random.default_rng(1000 + seed)
        t = times(log, generator)
        motion = random_fourier(limits, seed=seed, frequency_hz=log.motion_hz)
        q, dq, ddq = motion.evaluate(t)
        tau = model.predict(theta, *motion.evaluate(t - case.delay))  # the torque of ``delay`` seconds before
        if case.parallelogram:
            tau = tau + motor_friction(dq)
        if case.compensated:
            zero = np.zeros_like(q)
            tau = tau - model.predict(described, q, zero, zero)
        if spread is None:
            spread = tau.std(axis=0)
        tau = tau + generator.normal(0.0, 1.0, tau.shape) * NOISE * spread
        if case.mastering:  # the encoders read ``q + δ``: the description's zeros are not the robot's
            q = q + np.asarray(case.mastering)
        t, q, dq, tau, frame = logged(t, q, dq, tau, log, generator)
        records[role] = Record(t, q, tau, dq if log.velocity else None)
        if case.parallelogram:  # θ_m = R q, τ_m = R⁻ᵀ τ
            matrix = transmission_matrix(n)
            frame = {"t": t, **{f"qm{j + 1}": (q @ matrix.T)[:, j] for j in range(n)},
                     **{f"taum{j + 1}": np.linalg.solve(matrix.T, tau.T).T[:, j] for j in range(n)}}
        files[role] = folder / f"{role}.csv"
        pd.DataFrame(frame).to_csv(files[role], index=False, float_format="%.12g")
    return urdf, records, files, spread, options


def run_rig(case: Rig, folder: Path) -> dict:
    """Write the records, run the verbs and the plain fit: per joint test MSE of each on the same samples, and
    whether ``oed predict`` reproduces each verb's reported validation error."""
    from benchmarks.bench_real_robots import PlainFit

    urdf, records, files, spread, options = write_records(case, folder)
    plain = PlainFit(["--urdf", str(urdf)])
    rate = min(log.rate_hz for log in (case.train, case.validate, case.test))
    cutoff, plain_theta = plain_fit(plain, [records["train"]], [records["validate"]], rate)
    predicted_plain, kept = plain.predict(records["test"], cutoff, plain_theta)
    outcome = verbs_against_the_plain_fit(urdf, files, records["test"], kept, predicted_plain, folder,
                                          options=options)
    return {**outcome, "cutoff": cutoff, "floor": (NOISE * spread) ** 2}


def logs(seconds: tuple[float, float, float] = (10.0, 4.0, 6.0), rate: float = 250.0, velocity: bool = False,
         hz: tuple[float, float, float] = (0.2, 0.2, 0.2)) -> tuple[Log, Log, Log]:
    return tuple(Log(duration, rate, velocity=velocity, motion_hz=f) for duration, f in zip(seconds, hz))


RIGS = (
    Rig("PUMA 3 joints on a linear track (a horizontal prismatic axis, 60 kg carriage, fixed joint to the base), "
        "8 s / 3 s / 5 s at 250 Hz, no dq", puma_urdf(3, on_track=True), *logs((8.0, 3.0, 5.0))),
    Rig("PUMA 6 joints on a linear track, 10 s / 4 s / 6 s at 250 Hz, no dq", puma_urdf(6, on_track=True),
        *logs(), slow=True),
    Rig("a light 7-joint arm, joints 1, 3, 5, 7 continuous (no limits), massless end-effector and tool frames on "
        "fixed joints, 10 s / 4 s / 6 s at 500 Hz, logged dq", seven_joint_urdf, *logs(rate=500.0, velocity=True),
        slow=True),
    Rig("PUMA 6 joints, a 2.5 kg tool on the flange not in the URDF, 10 s / 4 s / 6 s at 250 Hz, no dq",
        puma_urdf(6), *logs(), tool=True, slow=True),
    Rig("PUMA 6 joints, the logged torque minus the controller's gravity model (the URDF's bodies), 10 s / 4 s / "
        "6 s at 250 Hz, no dq", puma_urdf(6), *logs(), compensated=True, slow=True),
    # h-gravity: both verbs say the torques hold no gravity load and fit without gravity (the mount check's gravity
    # (0, 0, 0), taken on the validation record): identify 0.133/0.037/0.238/0.526/0.161/0.531 of the plain fit, 0.142
    # in total (0.475 with the description's gravity), diagnose the same (0.553), no armature named. Joints 2 and 3
    # stay 3.6x and 5.5x their floor: the error of the controller's gravity model (the description's bodies, ±20 % off
    # the truth) is a load of the positions no model without gravity holds. h-subtracted: both verbs take the
    # model of a log less the description's gravity torque (the torques with it added back), every joint at its
    # floor (0.99-1.08x), 0.108 of the plain fit in total
    Rig("PUMA 6 joints, torques logged 8 ms after the positions, 10 s / 4 s / 6 s at 500 Hz, logged dq",
        puma_urdf(6), *logs(rate=500.0, velocity=True), delay=0.008, named=r"delay.*", slow=True),
    Rig("PUMA 6 joints as a parallelogram arm (motor 3 turns q2 + q3), motor side, --transmission, motor 3's "
        "friction on joints 2 and 3, 10 s / 4 s / 6 s at 250 Hz, no dq", puma_urdf(6), *logs(), parallelogram=True,
        # a strict xfail until a candidate removed as within its noise could return (h-armature): the offset on
        # tau3, removed while tau2 still lacked its Coulomb law, never came back and an armature on tau3 (Ia3
        # 0.0268 ± 0.0019 kg m², 14 standard deviations, the truth has none) stood in for it
        named=r"((coulomb|viscous)\[q2\+q3\]|motor_(coulomb|viscous)\[m3\]) on tau2,tau3", slow=True),
    Rig("PUMA 6 joints, encoders mastered 1.5° and -1° off the URDF's zeros on joints 2 and 3, 10 s / 4 s / 6 s at "
        "250 Hz, no dq", puma_urdf(6), *logs(), mastering=(0.0, np.radians(1.5), np.radians(-1.0), 0.0, 0.0, 0.0),
        slow=True),
    Rig("PUMA 6 joints, training and validation slow (0.05 Hz), the test at 0.2 Hz, 20 s / 8 s / 6 s at 250 Hz, "
        "no dq", puma_urdf(6), *logs((20.0, 8.0, 6.0), hz=(0.05, 0.05, 0.2)), slow=True),
)


@pytest.mark.parametrize("case", [pytest.param(case, id=case.name, marks=marks(case)) for case in RIGS])
def test_the_defaults_run_and_predict_a_rigs_log_as_well_as_a_plain_fit(case, tmp_path):
    outcome = run_rig(case, tmp_path)
    absolute = {label: values.round(5).tolist() for label, values in outcome["mse"].items()}
    as_well_as_the_plain_fit(case.name, outcome, f"chosen {outcome['selections']}; floor "
                             f"{outcome['floor'].round(5).tolist()}; test MSE {absolute}; ")
    assert all(error < RELATIVE for error in outcome["reproduced"].values()), outcome["reproduced"]
    said = json.loads((tmp_path / "default.json").read_text())["warnings"]
    assert not [text for text in said if "gravity load points elsewhere" in text], said  # every rig on the floor
    # torques logged without gravity (the controller's model subtracted): both verbs say the torques hold none and
    # take the exact model of that log, the description's gravity torque subtracted (h-subtracted: the result files
    # hold `subtracted`, the description's gravity, and `oed predict` reproduced the reported error above); every
    # other rig keeps the description's gravity and subtracts nothing
    for label in ("default", "diagnose"):
        document = json.loads((tmp_path / f"{label}.json").read_text())
        warned = document["warnings"] if isinstance(document["warnings"], list) else \
            [text for part in document["warnings"].values() for text in part]
        assert bool([text for text in warned if "hold no gravity load" in text]) == case.compensated, (label, warned)
        assert np.any(document["model_file"]["gravity"]), (label, document["model_file"]["gravity"])
        subtracted = document["model_file"].get("subtracted")
        assert (subtracted or {}).get("kind") == ("description_gravity" if case.compensated else None), (label,
                                                                                                          subtracted)
    allowed = PLAIN + (f"|{case.named}" if case.named else "")
    named = outcome["effects"].get("diagnose", [])
    assert all(re.fullmatch(allowed, effect) for effect in named), named
