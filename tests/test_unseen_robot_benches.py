"""Bench rigs and cheap robots the project has not seen (issue 34), beside the other ``tests/test_unseen_robot*``
files:

- a one-joint pendulum (a hand-written URDF: a horizontal axis, gravity the largest load), its test point-to-point
  moves with rests;
- the same pendulum driven by a hobby servo: its potentiometer read to 0.3° (5.2 mrad), logged at 50 Hz;
- a hobby servo arm (the project's four-joint ``servo_arm``) whose encoders read 0.3°, at 100 Hz, no velocity;
- a six-joint arm logged at 50 Hz only (a slow fieldbus or a ROS topic throttled), no velocity;
- a planar arm whose three axes are vertical (a SCARA's without the quill): no gravity load, its gravity
  parameters unidentifiable, its test point-to-point;
- the pendulum trained on one side of its swing, tested over the whole;
- the servo arm logged at 25 Hz (its motion's fifth harmonic at 1 Hz, the rate still 25 times that);
- the servo arm's angles logged in degrees, no units row, nothing declared: the verbs exit naming the option that
  reads the log as it is, and with that option predict as well as the plain fit;
- a torque sensor with hysteresis (a play of 8 % of the channel's spread on joint 2: the reading lags the torque by
  up to that when the torque turns back), a truth outside every candidate family: nothing beyond the plain
  class's friction may be named.

No data are copied; every record is simulated here as :mod:`tests.test_unseen_robot_labs` does (the plain fit's
model class, :func:`tests.test_unseen_robots.truth`, each case's effect, white torque noise of 2 % of each
channel's spread).

Each case runs the default ``oed identify`` (told the plain fit's model class) and ``oed diagnose`` (its own
defaults), then ``oed predict`` on the test record that no choice saw, against the plain Pinocchio least-squares
fit of ``benchmarks/bench_real_robots.py`` (its cut-off chosen on the validation record) on the same recorded
samples: per joint within 1.3x, in total at most 1.0x, each figure allowed its noise floor's sampling spread; and
``oed predict`` on the validation record reproduces the validation error each verb reported (relative 1e-6)."""

from __future__ import annotations

import functools
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dynamics.robots import load_robot
from tests.test_one_answer_audit import RELATIVE
from tests.test_unseen_robot_kinds import as_well_as_the_plain_fit, named_law, quiet
from tests.test_unseen_robot_labs import Lab, puma, run_lab, write_records
from tests.test_unseen_robots import Log

PI = np.pi
SERVO_QUANTUM = np.radians(0.3)  # a hobby servo's potentiometer read through a 10-bit converter over 300°

PENDULUM = """<?xml version="1.0"?>
<robot name="pendulum">
  <link name="world"/>
  <joint name="stand" type="fixed"><origin xyz="0 0 0.8"/><parent link="world"/><child link="hub"/></joint>
  <link name="hub"><inertial><origin xyz="0 0 0"/><mass value="3"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <joint name="swing" type="revolute"><origin xyz="0 0.05 0"/><axis xyz="0 1 0"/><parent link="hub"/><child link="rod"/>
    <limit lower="-2.6" upper="2.6" velocity="4.0" effort="40"/></joint>
  <link name="rod"><inertial><origin xyz="0 0 -0.22"/><mass value="1.6"/><inertia ixx="0.03" ixy="0" ixz="0" iyy="0.031" iyz="0" izz="0.0015"/></inertial></link>
  <joint name="bob_mount" type="fixed"><origin xyz="0 0 -0.45"/><parent link="rod"/><child link="bob"/></joint>
  <link name="bob"><inertial><origin xyz="0.01 0 0"/><mass value="0.8"/><inertia ixx="0.0008" ixy="0" ixz="0" iyy="0.0008" iyz="0" izz="0.0008"/></inertial></link>
</robot>
"""

PLANAR = """<?xml version="1.0"?>
<robot name="planar_arm">
  <link name="table"/>
  <joint name="column" type="fixed"><origin xyz="0 0 0.3"/><parent link="table"/><child link="base"/></joint>
  <link name="base"><inertial><origin xyz="0 0 -0.1"/><mass value="8"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.05"/></inertial></link>
  <joint name="first" type="revolute"><origin xyz="0 0 0.05"/><axis xyz="0 0 1"/><parent link="base"/><child link="upper"/>
    <limit lower="-2.5" upper="2.5" velocity="2.5" effort="120"/></joint>
  <link name="upper"><inertial><origin xyz="0.18 0.01 0.02"/><mass value="6"/><inertia ixx="0.01" ixy="0" ixz="0.001" iyy="0.08" iyz="0" izz="0.078"/></inertial></link>
  <joint name="second" type="revolute"><origin xyz="0.4 0 0.04"/><axis xyz="0 0 1"/><parent link="upper"/><child link="fore"/>
    <limit lower="-2.4" upper="2.4" velocity="3.0" effort="60"/></joint>
  <link name="fore"><inertial><origin xyz="0.14 -0.01 0.01"/><mass value="3.5"/><inertia ixx="0.005" ixy="0.0005" ixz="0" iyy="0.03" iyz="0" izz="0.029"/></inertial></link>
  <joint name="third" type="revolute"><origin xyz="0.3 0 0.03"/><axis xyz="0 0 1"/><parent link="fore"/><child link="hand"/>
    <limit lower="-2.8" upper="2.8" velocity="4.0" effort="20"/></joint>
  <link name="hand"><inertial><origin xyz="0.06 0 0"/><mass value="1.2"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.003" iyz="0" izz="0.003"/></inertial></link>
</robot>
"""


@functools.cache
def written(text: str) -> Path:
    """``text`` written once as a URDF file of its own (a temporary folder that outlives the test session's
    cases)."""
    path = Path(tempfile.mkdtemp(prefix="unseen-benches-")) / "description.urdf"
    path.write_text(text, encoding="utf-8")  # a vendor's joint names may hold accents
    return path


def pendulum():
    return load_robot(urdf=written(PENDULUM))


def planar():
    return load_robot(urdf=written(PLANAR))


def servo_arm():
    return load_robot("servo_arm")


def played(tau: np.ndarray, spread: np.ndarray, joint: int = 1, share: float = 0.08) -> np.ndarray:
    """A torque sensor's hysteresis on ``joint``: the play operator of half-width ``share`` of the channel's
    ``spread`` (Krasnosel'skii and Pokrovskii; Visintin, *Differential Models of Hysteresis*, 1994, ch. III):
    ``y_k = min(τ_k + r, max(τ_k − r, y_{k−1}))``, ``y_0 = τ_0``; the reading stays until the torque has moved
    ``r`` past it, so it lags by up to ``r`` after each turn. The other channels as they are."""
    out = tau.copy()
    width = share * spread[joint]
    reading = tau[0, joint]
    for k in range(tau.shape[0]):
        reading = min(tau[k, joint] + width, max(tau[k, joint] - width, reading))
        out[k, joint] = reading
    return out


@dataclass(frozen=True)
class Bench:
    """One case: the lab's records (:class:`tests.test_unseen_robot_labs.Lab`) and the effects a verb may name
    (the truth's own; any other is a false effect)."""

    lab: Lab
    may_name: tuple[str, ...] = ("coulomb", "viscous", "offset")

    @property
    def name(self) -> str:
        return self.lab.name


def no_servo(seconds: tuple[float, float, float], rate: float, **changes) -> tuple[Log, Log, Log]:
    return tuple(Log(duration, rate, velocity=False, **changes) for duration in seconds)


BENCHES = (
    Bench(Lab("a one-joint pendulum (hand-written URDF, horizontal axis), 10 s / 4 s / 8 s at 250 Hz, no dq, "
              "point-to-point test", pendulum, *no_servo((10.0, 4.0, 8.0), 250.0), test_motion="point-to-point",
              slow=True)),
    Bench(Lab("the pendulum on a hobby servo: 0.3° potentiometer, 50 Hz, no dq, 12 s / 4 s / 8 s, point-to-point "
              "test", pendulum, *no_servo((12.0, 4.0, 8.0), 50.0, quantum=SERVO_QUANTUM),
              test_motion="point-to-point", slow=True)),
    Bench(Lab("the four-joint servo arm, 0.3° encoders, 100 Hz, no dq, 10 s / 4 s / 6 s", servo_arm,
              *no_servo((10.0, 4.0, 6.0), 100.0, quantum=SERVO_QUANTUM), slow=True)),
    Bench(Lab("PUMA 6 joints logged at 50 Hz, no dq, 12 s / 4 s / 8 s, point-to-point test", puma(6),
              *no_servo((12.0, 4.0, 8.0), 50.0), test_motion="point-to-point", slow=True)),
    Bench(Lab("a planar arm, three vertical axes (no gravity load), 10 s / 4 s / 8 s at 250 Hz, no dq, "
              "point-to-point test", planar, *no_servo((10.0, 4.0, 8.0), 250.0), test_motion="point-to-point",
              slow=True)),
    # until h-tie20 a strict xfail: diagnose 38.8x the plain fit (the offset, 'not significant' on the short swing,
    # left out; the plain law completed validating 1.000 against 1.008, within the 1 % band then kept by the model
    # with fewer laws); the lower score now decides: diagnose 1.045, as identify
    Bench(Lab("the pendulum trained and validated on its lowest 35 % of swing (-2.6 to -0.78 rad), tested over the "
              "whole swing, 10 s / 4 s / 8 s at 250 Hz, no dq", pendulum, *no_servo((10.0, 4.0, 8.0), 250.0),
              trained_range=(0, 0.35), slow=True)),
    Bench(Lab("the four-joint servo arm logged at 25 Hz, 0.3° encoders, no dq, 16 s / 6 s / 8 s, point-to-point "
              "test", servo_arm, *no_servo((16.0, 6.0, 8.0), 25.0, quantum=SERVO_QUANTUM),
              test_motion="point-to-point", slow=True)),
    Bench(Lab("PUMA 3 joints, joint 2's torque sensor with hysteresis (a play of 8 % of its spread), 10 s / 4 s / "
              "6 s at 250 Hz, no dq", puma(3), *no_servo((10.0, 4.0, 6.0), 250.0), sensed=played, slow=True,
              xfail="diagnose 1.028 in total (joint 2 1.074x; identify 0.979, joint 2 1.008x): the offset on "
                    "tau2, significant on training (p = 2e-17), raised the validation error 4.143 -> 4.18 and "
                    "was rejected; the plain law completed validates 1.011 against 1.002, not taken; on the test "
                    "it would have lowered joint 2's error; nothing false named, and tau2 said 6.8x above its "
                    "floor, following none of the traced variables. h-tie20: a tie band that keeps the plain class "
                    "(the completion taken unless the adopted model validates more than 1 % lower) passes it "
                    "(0.979, joint 2 1.008x) but makes the TX40's diagnose 0.418 -> 0.424 (joint 1 0.897 -> 0.918; "
                    "its completion 1.0131 against 1.0084): not kept")),
)


def marks(bench: Bench) -> list[pytest.MarkDecorator]:
    chosen = [pytest.mark.slow] if bench.lab.slow else []
    if bench.lab.xfail:
        chosen.append(pytest.mark.xfail(strict=True, reason=bench.lab.xfail))
    return chosen


def judged(bench: Bench, folder: Path, rewritten=None, **running) -> None:
    """Run ``bench`` (:func:`tests.test_unseen_robot_labs.run_lab`, each file rewritten by ``rewritten``, with
    ``running``: its ``reading``, ``options``, ``seconds``) and check it: every verb within the plain fit's margins,
    ``oed predict`` reproducing each reported validation error, no effect named beyond ``bench.may_name``."""
    outcome = run_lab(bench.lab, folder, rewritten=rewritten, **running)
    print(f"\nreproduced validation error (relative): {outcome['reproduced']}")
    as_well_as_the_plain_fit(bench.name, outcome, f"chosen {outcome['selections']}; ")
    for label, error in outcome["reproduced"].items():
        assert error < RELATIVE, (label, error)
    for label, named in outcome["effects"].items():
        false = [effect for effect in named if named_law(effect) not in bench.may_name]
        assert not false, (label, false)


@pytest.mark.parametrize("bench", [pytest.param(bench, id=bench.name, marks=marks(bench)) for bench in BENCHES])
def test_the_defaults_run_and_predict_a_benchs_log_as_well_as_a_plain_fit(bench, tmp_path):
    judged(bench, tmp_path)


def test_the_pendulums_description_reads_as_one_joint_under_gravity():
    """The hand-written pendulum: one revolute joint about a horizontal axis, the rod and the bob (fixed to it)
    its body: the static torque at 90° is the bodies' weight times their lever (rod 1.6 kg at 0.22 m, bob 0.8 kg
    at 0.45 m)."""
    from dynamics.models import build_model

    model = build_model(pendulum(), "internal", "viscous")
    theta = np.r_[pendulum().standard_parameters, 0.0]
    held = model.predict(theta, np.array([[PI / 2]]), np.zeros((1, 1)), np.zeros((1, 1)))
    assert abs(held[0, 0]) == pytest.approx(9.81 * (1.6 * 0.22 + 0.8 * 0.45), rel=0.02)


def in_degrees(path: Path) -> None:
    """The log's angle columns (``q1..``) rewritten in degrees, as a logger that writes what a servo's display
    shows would; no units row."""
    table = pd.read_csv(path)
    angles = [column for column in table.columns if re.fullmatch(r"q\d+", column)]
    table[angles] = np.degrees(table[angles])
    table.to_csv(path, index=False, float_format="%.10g")


def said_option(message: str) -> tuple[str, str]:
    """The ``--columns`` option an angle unit error names."""
    found = re.search(r"(--columns) (q=[\d.e-]+\*q)", message)
    assert found, message
    return found.group(1), found.group(2)


@pytest.mark.slow
def test_angles_in_degrees_exit_naming_the_option_that_reads_them(tmp_path):
    """The default ``oed identify`` on the servo arm's log in degrees exits (code 2, no traceback) naming
    the ``--columns`` factor that reads it."""
    urdf, _, files, _ = write_records(BENCHES[2].lab, tmp_path)
    in_degrees(files["train"])
    code, message = quiet(["identify", "--urdf", str(urdf), "--data", str(files["train"]), "--out",
                           str(tmp_path / "result.json")])
    assert code == 2 and "look like degrees" in message and "Traceback" not in message, message
    assert said_option(message)[1] == f"q={np.pi / 180.0!r}*q"


@pytest.mark.slow
def test_with_the_option_the_error_names_a_log_in_degrees_predicts_as_well_as_a_plain_fit(tmp_path):
    """The servo arm's three records in degrees: the option the error names, given to every verb (identify,
    diagnose, predict), and the result as good as the plain fit's on the log in radians."""
    lab = BENCHES[2].lab
    (tmp_path / "probe").mkdir()
    urdf, _, files, _ = write_records(lab, tmp_path / "probe")
    in_degrees(files["train"])
    code, message = quiet(["diagnose", "--urdf", str(urdf), "--data", str(files["train"]), "--validate",
                           str(files["validate"]), "--out", str(tmp_path / "probe" / "result.json")])
    assert code == 2, message
    outcome = run_lab(lab, tmp_path, rewritten=in_degrees, reading=said_option(message))
    as_well_as_the_plain_fit(f"{lab.name}, in degrees", outcome, f"chosen {outcome['selections']}; ")
    for label, error in outcome["reproduced"].items():
        assert error < RELATIVE, (label, error)


def test_the_degrees_option_is_named_only_where_it_reads_every_joint_right():
    """On a robot with a prismatic joint the group factor would scale its metres too: the message then names only
    the conversion; on one whose joints all turn it names the option."""
    from dynamics.models import build_model
    from estimation.data.loading import AngleUnitError, check_angles

    here = Path(__file__).resolve().parent
    mixed = build_model(load_robot(urdf=here / "data" / "prismatic_arm.urdf"), "internal", "viscous")
    turning = build_model(servo_arm(), "internal", "viscous")
    angles = np.degrees(np.linspace(-1.0, 1.0, 50))
    for model, named in ((mixed, False), (turning, True)):
        q = np.column_stack([angles] + [np.zeros_like(angles)] * (model.robot.n_joints - 1))
        with pytest.raises(AngleUnitError, match="look like degrees") as raised:
            check_angles(q, model, "log.csv")
        assert ("--columns" in str(raised.value)) is named, str(raised.value)
