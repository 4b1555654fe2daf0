"""Kinds of robot and log the project has not seen (issue 34's table), beside :mod:`tests.test_unseen_robots`: a
UR10e-like arm tested on a point-to-point motion after Fourier training, a Schunk-like arm of many short records
(``--data`` and ``--validate`` repeated), a heavy industrial arm (KR300-like: hundreds of kilograms, large Coulomb
friction, a slow motion), a description with a continuous joint, no limits on it and fixed joints (a mount, a
camera, a flange and a tool merged into the links they hang on), and a torque log with a constant sensor offset,
quantised torques and its columns in another order among others the reader ignores.

The descriptions are written here by hand: the UR10e's published DH table and link masses and centres of mass
(Universal Robots, "DH parameters for calculations of kinematics and dynamics"), the inertias of solid cylinders
of those masses; the KR300 R2500 and the Schunk LWA 4P from their published lengths, limits and total masses
split over the links by hand. No data are copied: every record is simulated by the test (the truth is the plain
fit's model class, :func:`tests.test_unseen_robots.truth`, with the noise of that module).

Each case runs the default ``oed identify`` (told the plain fit's model class) and ``oed diagnose`` (its own
defaults), then ``oed predict`` on the test record(s), against the plain Pinocchio least-squares fit of
``benchmarks/bench_real_robots.py`` (its cut-off chosen on the validation record(s)), on the same recorded samples:
per joint within 1.3x, in total at most 1.0x, each figure allowed its noise floor's sampling spread."""

from __future__ import annotations

import contextlib
import io
import json
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from dynamics.dh import DHLink, robot_from_dh
from dynamics.models import build_model
from dynamics.robot import inertial_parameters
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import true_parameters
from dynamics.urdf_export import robot_urdf
from oed.fourier import random_fourier
from tests.test_unseen_robots import FRICTION, NOISE, PER_JOINT, TOTAL, Log, truth, within

PI = np.pi


def cylinder(mass: float, length: float, radius: float, axis: int, com) -> tuple[float, ...]:
    """The ten standard parameters of a solid cylinder of ``mass`` along link-frame axis ``axis`` (0, 1, 2) centred
    at ``com``."""
    along = mass * (3.0 * radius**2 + length**2) / 12.0
    across = mass * radius**2 / 2.0
    diagonal = [along, along, along]
    diagonal[axis] = across
    return tuple(inertial_parameters(mass, com, (*diagonal, 0.0, 0.0, 0.0)))


def ur10e():
    """The UR10e's published DH table (m, rad), link masses (kg) and centres of mass (m, in the DH frames); the
    limits of its data sheet (±360°, 120°/s on the base and shoulder, 180°/s on the others)."""
    a = (0.0, -0.6127, -0.57155, 0.0, 0.0, 0.0)
    d = (0.1807, 0.0, 0.0, 0.17415, 0.11985, 0.11655)
    alpha = (PI / 2, 0.0, 0.0, PI / 2, -PI / 2, 0.0)
    mass = (7.369, 13.051, 3.989, 2.1, 1.98, 0.615)
    com = ((0.021, -0.027, 0.0), (0.38, 0.0, 0.158), (0.24, 0.0, 0.068), (0.0, 0.007, 0.018), (0.0, 0.007, 0.018),
           (0.0, 0.0, -0.026))
    shape = ((0.2, 0.075, 1), (0.6127, 0.075, 0), (0.57155, 0.06, 0), (0.12, 0.045, 1), (0.12, 0.045, 1),
             (0.05, 0.045, 2))
    velocity = (2.094, 2.094, 3.142, 3.142, 3.142, 3.142)
    effort = (330.0, 330.0, 150.0, 56.0, 56.0, 56.0)
    links = [DHLink(a[j], alpha[j], d[j], inertial=cylinder(mass[j], *shape[j], com[j]), lower=-2 * PI, upper=2 * PI,
                    velocity=velocity[j], effort=effort[j]) for j in range(6)]
    return robot_from_dh("ur10e", links, joint_names=[f"ur_joint{j + 1}" for j in range(6)])


def kr300():
    """A KR300 R2500-like heavy arm: its published lengths (a1 0.35, d1 0.675, a2 1.15, a3 0.041, d4 1.0, d6 0.24
    m), ranges and speeds (105, 101, 107, 136, 129, 206 °/s); its 1120 kg split by hand over the moving links,
    with a 250 kg payload on the flange."""
    deg = PI / 180.0
    rows = ((0.35, -PI / 2, 0.675), (1.15, 0.0, 0.0), (0.041, -PI / 2, 0.0), (0.0, PI / 2, 1.0), (0.0, -PI / 2, 0.0),
            (0.0, 0.0, 0.24))
    mass = (420.0, 230.0, 190.0, 60.0, 35.0, 260.0)
    shape = ((0.7, 0.35, 1, (-0.1, 0.25, 0.0)), (1.15, 0.2, 0, (-0.55, 0.0, 0.15)), (0.5, 0.2, 1, (0.0, 0.0, 0.1)),
             (0.6, 0.12, 1, (0.0, -0.25, 0.0)), (0.25, 0.1, 2, (0.0, 0.0, 0.02)), (0.3, 0.25, 2, (0.0, 0.0, 0.15)))
    lower = np.array((-185.0, -140.0, -120.0, -350.0, -125.0, -350.0)) * deg
    upper = np.array((185.0, -5.0, 168.0, 350.0, 125.0, 350.0)) * deg
    velocity = np.array((105.0, 101.0, 107.0, 136.0, 129.0, 206.0)) * deg
    links = [DHLink(*rows[j], inertial=cylinder(mass[j], *shape[j][:3], shape[j][3]), lower=lower[j], upper=upper[j],
                    velocity=velocity[j], effort=8000.0) for j in range(6)]
    return robot_from_dh("kr300_r2500", links)


def lwa4p():
    """A Schunk LWA 4P-like arm of six modules: its published lengths (d1 0.205, a2 0.35, d4 0.305, d6 0.0845 m),
    ±170° ranges at 72°/s, its 15 kg split by hand over the modules."""
    rows = ((0.0, -PI / 2, 0.205), (0.35, PI, 0.0), (0.0, -PI / 2, 0.0), (0.0, PI / 2, 0.305), (0.0, -PI / 2, 0.0),
            (0.0, 0.0, 0.0845))
    mass = (3.6, 3.2, 2.4, 2.2, 1.4, 0.8)
    shape = ((0.2, 0.07, 1, (0.0, 0.05, 0.0)), (0.35, 0.06, 0, (-0.17, 0.0, 0.02)), (0.12, 0.06, 1, (0.0, 0.0, 0.03)),
             (0.3, 0.05, 1, (0.0, -0.12, 0.0)), (0.1, 0.05, 2, (0.0, 0.0, 0.01)), (0.08, 0.04, 2, (0.0, 0.0, 0.03)))
    links = [DHLink(*rows[j], inertial=cylinder(mass[j], *shape[j][:3], shape[j][3]), lower=-2.967, upper=2.967,
                    velocity=1.257, effort=200.0) for j in range(6)]
    return robot_from_dh("lwa4p", links)


#: a four-joint arm on a fixed mount: a continuous base joint with no <limit>, a camera and a tool on fixed joints
#: (merged into the links they hang on), a continuous wrist (whose <limit> gives its effort and speed only)
CONTINUOUS_ARM = """<?xml version="1.0"?>
<robot name="continuous_arm">
  <link name="world"/>
  <joint name="mount" type="fixed"><origin xyz="0 0 0.4" rpy="0 0 0.3"/><parent link="world"/><child link="pedestal"/></joint>
  <link name="pedestal"><inertial><origin xyz="0 0 -0.2"/><mass value="20"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="0.5"/></inertial></link>
  <joint name="base_yaw" type="continuous"><origin xyz="0 0 0.05"/><axis xyz="0 0 1"/><parent link="pedestal"/><child link="turret"/></joint>
  <link name="turret"><inertial><origin xyz="0.02 0 0.1"/><mass value="4.0"/><inertia ixx="0.03" ixy="0" ixz="0" iyy="0.03" iyz="0" izz="0.02"/></inertial></link>
  <joint name="camera_mount" type="fixed"><origin xyz="0 0.1 0.15" rpy="0 0.4 0"/><parent link="turret"/><child link="camera"/></joint>
  <link name="camera"><inertial><origin xyz="0.03 0 0"/><mass value="0.6"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.002" iyz="0" izz="0.002"/></inertial></link>
  <joint name="shoulder" type="revolute"><origin xyz="0 0 0.2"/><axis xyz="0 1 0"/><parent link="turret"/><child link="upper_arm"/>
    <limit lower="-1.8" upper="1.8" velocity="1.5" effort="150"/></joint>
  <link name="upper_arm"><inertial><origin xyz="0.2 0 0"/><mass value="3.0"/><inertia ixx="0.004" ixy="0" ixz="0" iyy="0.045" iyz="0" izz="0.045"/></inertial></link>
  <joint name="elbow" type="revolute"><origin xyz="0.4 0 0"/><axis xyz="0 1 0"/><parent link="upper_arm"/><child link="forearm"/>
    <limit lower="-2.2" upper="2.2" velocity="2.0" effort="80"/></joint>
  <link name="forearm"><inertial><origin xyz="0.15 0 0.01"/><mass value="1.8"/><inertia ixx="0.002" ixy="0" ixz="0" iyy="0.015" iyz="0" izz="0.015"/></inertial></link>
  <joint name="wrist_roll" type="continuous"><origin xyz="0.32 0 0"/><axis xyz="1 0 0"/><parent link="forearm"/><child link="wrist"/>
    <limit velocity="3.0" effort="20"/></joint>
  <link name="wrist"><inertial><origin xyz="0.03 0.01 0.02"/><mass value="0.7"/><inertia ixx="0.0008" ixy="0" ixz="0" iyy="0.0006" iyz="0" izz="0.0006"/></inertial></link>
  <joint name="flange" type="fixed"><origin xyz="0.08 0 0"/><parent link="wrist"/><child link="tool"/></joint>
  <link name="tool"><inertial><origin xyz="0.05 0 0.03"/><mass value="1.2"/><inertia ixx="0.002" ixy="0" ixz="0" iyy="0.003" iyz="0" izz="0.003"/></inertial></link>
  <joint name="tool_tip" type="fixed"><origin xyz="0.1 0 0"/><parent link="tool"/><child link="tcp"/></joint>
  <link name="tcp"/>
</robot>
"""

#: the motion's limits for the continuous joints, which the description leaves open (rad, rad/s)
CONTINUOUS_MOTION = {0: (-PI, PI, 1.5), 3: (-PI, PI, 3.0)}


@dataclass(frozen=True)
class Kind:
    """One case: the robot (a function writing its URDF into a folder), the logs of each role (several records a
    role with ``records``), the test record's motion, and the truth's friction."""

    name: str
    urdf: object  # folder -> Path
    train: Log
    validate: Log
    test: Log
    records: tuple[int, int, int] = (1, 1, 1)
    test_motion: str = "fourier"  # or "point-to-point": minimum-jerk moves between rests
    coulomb: tuple[float, ...] | None = None  # default truth()'s
    viscous: tuple[float, ...] | None = None
    torque_bias: float = 0.0  # a sensor's constant offset, of each channel's spread
    torque_quantum: float = 0.0  # the torques' resolution, of each channel's spread
    columns: str = "plain"  # or "shuffled": other order, blanks around names, columns the reader ignores
    motion_limits: dict = field(default_factory=dict)  # joint -> (lower, upper, velocity) where the URDF has none
    slow: bool = False
    xfail: str = ""


def dh_urdf(build):
    def write(folder: Path) -> Path:
        path = folder / "robot.urdf"
        path.write_text(robot_urdf(build()))
        return path
    return write


def text_urdf(text: str):
    def write(folder: Path) -> Path:
        path = folder / "robot.urdf"
        path.write_text(text)
        return path
    return write


def builtin(name: str, joints: int):
    def write(folder: Path) -> Path:
        path = folder / "robot.urdf"
        path.write_text(robot_urdf(load_robot(name, joints=joints)))
        return path
    return write


def motion_limits(robot, limits: dict) -> SimpleNamespace:
    """The robot's joint ranges and speeds, with ``limits`` where the description has none."""
    lower, upper, velocity = (np.array(values, dtype=float) for values in (robot.lower, robot.upper,
                                                                            robot.velocity_limit))
    for joint, (low, high, speed) in limits.items():
        lower[joint], upper[joint], velocity[joint] = low, high, speed
    return SimpleNamespace(n_joints=robot.n_joints, lower=lower, upper=upper, velocity_limit=velocity)


def minimum_jerk(s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``10 s³ − 15 s⁴ + 6 s⁵`` and its first two derivatives in ``s``."""
    return (10 * s**3 - 15 * s**4 + 6 * s**5, 30 * s**2 - 60 * s**3 + 30 * s**4, 60 * s - 180 * s**2 + 120 * s**3)


def point_to_point(limits: SimpleNamespace, seed: int, t: np.ndarray, rest: float = 0.4
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Minimum-jerk moves of all joints together between random poses (within 60 % of each half range about the
    centre), each move as long as the slowest joint needs at 70 % of its speed limit (at least 0.6 s), a rest of
    ``rest`` seconds after each: another kind of motion than a Fourier series, with stops."""
    generator = np.random.default_rng(seed)
    centre, half = 0.5 * (limits.lower + limits.upper), 0.5 * (limits.upper - limits.lower)
    q, dq, ddq = (np.zeros((t.shape[0], limits.n_joints)) for _ in range(3))
    start, pose, clock = t[0], centre.copy(), t[0]
    q[:] = pose
    while clock < t[-1]:
        target = centre + generator.uniform(-0.6, 0.6, limits.n_joints) * half
        step = target - pose
        duration = max(0.6, float(np.max(1.875 * np.abs(step) / (0.7 * limits.velocity_limit))))
        inside = (t >= clock) & (t < clock + duration)
        s = (t[inside] - clock) / duration
        position, speed, acceleration = minimum_jerk(s)
        q[inside] = pose + np.outer(position, step)
        dq[inside] = np.outer(speed, step) / duration
        ddq[inside] = np.outer(acceleration, step) / duration**2
        after = t >= clock + duration
        q[after], dq[after], ddq[after] = target, 0.0, 0.0
        pose, clock = target, clock + duration + rest
    del start
    return q, dq, ddq


def write_record(model, theta, limits, kind: Kind, log: Log, motion: str, seed: int, path: Path,
                 spread: np.ndarray | None):
    """One record (another motion a seed) as :func:`tests.test_unseen_robots.write_record`, with this kind's
    sensor offset, torque resolution and column layout; returns the plain fit's view of it and the spread."""
    from benchmarks.bench_real_robots import Record
    from tests.test_unseen_robots import logged, times

    generator = np.random.default_rng(1000 + seed)
    t = times(log, generator)
    if motion == "point-to-point":
        q, dq, ddq = point_to_point(limits, seed, t)
    else:
        q, dq, ddq = random_fourier(limits, seed=seed, frequency_hz=log.motion_hz).evaluate(t)
    tau = model.predict(theta, q, dq, ddq)
    if spread is None:
        spread = tau.std(axis=0)
    tau = tau + generator.normal(0.0, 1.0, tau.shape) * NOISE * spread + kind.torque_bias * spread
    if kind.torque_quantum:
        quantum = kind.torque_quantum * spread
        tau = np.round(tau / quantum) * quantum
    t, q, dq, tau, frame = logged(t, q, dq, tau, log, generator)
    table = pd.DataFrame(frame)
    if kind.columns == "shuffled":  # another order, blanks around the names, a controller's further columns
        for j in range(q.shape[1]):
            table[f"temperature{j + 1}"] = 35.0 + generator.normal(0.0, 0.1, t.shape[0])
        table["mode"] = 2
        order = list(generator.permutation(table.columns))
        table = table[order].rename(columns=lambda name: f" {name} ")
    table.to_csv(path, index=False, float_format="%.10g")
    return Record(t, q, tau, dq if log.velocity else None), spread


def quiet(arguments: list[str]) -> tuple[int, str]:
    from oed.cli import main

    with contextlib.redirect_stdout(io.StringIO()) as out, contextlib.redirect_stderr(io.StringIO()) as err:
        code = main(arguments)
    return code, err.getvalue().strip()[-800:] + out.getvalue()[-200:]


def plain_fit(plain, trains: list, validates: list, rate_hz: float) -> tuple[float, np.ndarray]:
    """:meth:`benchmarks.bench_real_robots.PlainFit.fit` over several records a role: each cut-off fitted on the
    training records' samples its filter keeps (stacked), scored on the validation records' samples the lowest
    cut-off keeps; cut-offs settling longer than a tenth of the shortest validation record are not tried."""
    from benchmarks.bench_real_robots import CUTOFFS_HZ, SETTLING, filtered_motion

    duration = min(record.t[-1] - record.t[0] for record in validates)
    cutoffs = [c for c in CUTOFFS_HZ if c < 0.4 * rate_hz and SETTLING / c <= 0.1 * duration]
    best = None
    for cutoff in cutoffs:
        rows, targets = [], []
        for record in trains:
            keep = plain.kept(record, cutoff)
            rows.append(plain.regressor(record, cutoff)[keep].reshape(-1, plain.columns.shape[0]))
            targets.append(filtered_motion(record, cutoff)[3][keep].reshape(-1))
        theta = np.linalg.lstsq(np.vstack(rows), np.concatenate(targets), rcond=None)[0]
        error = 0.0
        for record in validates:
            scored = plain.kept(record, min(cutoffs))
            error += float(np.sum((record.tau[scored] - (plain.regressor(record, cutoff) @ theta)[scored]) ** 2))
        if best is None or error < best[0]:
            best = (error, cutoff, theta)
    return best[1], best[2]


def write_records(kind: Kind, folder: Path) -> tuple[Path, dict, dict, np.ndarray]:
    """The robot's URDF and the records of each role written into ``folder``: ``(urdf, records, files,
    spread)``."""
    urdf = kind.urdf(folder)
    robot = load_robot(urdf=urdf)
    limits = motion_limits(robot, kind.motion_limits)
    model = build_model(robot, "internal", FRICTION)
    theta = truth(model)
    if kind.coulomb is not None or kind.viscous is not None:  # truth()'s, with this kind's friction
        n = robot.n_joints
        theta = true_parameters(model, seed=0, coulomb=np.asarray(kind.coulomb or np.linspace(1.0, 3.0, n)),
                                offset=np.linspace(0.5, 1.0, n) * (-1.0) ** np.arange(n),
                                **({} if kind.viscous is None else {"viscous": np.asarray(kind.viscous)}))
    spread, records, files = None, {}, {}
    for role, log, count, base in (("train", kind.train, kind.records[0], 11), ("validate", kind.validate,
                                                                               kind.records[1], 100),
                                   ("test", kind.test, kind.records[2], 200)):
        motion = kind.test_motion if role == "test" else "fourier"
        records[role], files[role] = [], []
        for index in range(count):
            path = folder / f"{role}{index + 1}.csv"
            record, spread = write_record(model, theta, limits, kind, log, motion, base + index, path, spread)
            records[role].append(record)
            files[role].append(path)
    return urdf, records, files, spread


def run_kind(kind: Kind, folder: Path) -> dict:
    """Write the records, run the verbs and the plain fit: per joint test MSE of each on the same samples."""
    from benchmarks.bench_real_robots import PlainFit, at_recorded, resent

    urdf, records, files, spread = write_records(kind, folder)
    data = [argument for path in files["train"] for argument in ("--data", str(path))]
    validate = [argument for path in files["validate"] for argument in ("--validate", str(path))]
    mse, exits = {}, {}
    plain = PlainFit(["--urdf", str(urdf)])
    cutoff, plain_theta = plain_fit(plain, records["train"], records["validate"], kind.train.rate_hz)
    selected = {}
    for label, verb, options in (("default", "identify", ["--friction", FRICTION]), ("diagnose", "diagnose", [])):
        result = folder / f"{label}.json"
        code, message = quiet([verb, "--urdf", str(urdf), *data, *validate, *options, "--out", str(result)])
        if code != 0:
            exits[label] = message
            continue
        summary = json.loads(result.read_text())
        named = {(effect["spec"], tuple(effect["channels"])) for effect in summary.get("effects", [])
                 if isinstance(effect, dict)}
        both = named & {(effect["spec"], tuple(effect["channels"])) for effect in summary.get("rejected", [])}
        assert not both, f"oed {verb}: effects both adopted and rejected: {sorted(both)}"
        selected[label] = [effect if isinstance(effect, str) else f"{effect['spec']} on {','.join(effect['channels'])}"
                           for effect in summary.get("effects", [])]
        squares, plain_squares, count = 0.0, 0.0, 0
        for index, (record, path) in enumerate(zip(records["test"], files["test"])):
            out = folder / f"{label}_test{index}.csv"
            code, message = quiet(["predict", "--model", str(result), "--data", str(path), "--out", str(out)])
            if code != 0:
                exits[label] = message
                break
            table = pd.read_csv(out)
            channels = [column for column in table.columns if column.startswith("tau") and column[3:].isdigit()]
            rows, values = at_recorded(record.t, table["t"].to_numpy(), table[channels].to_numpy())
            predicted, kept = plain.predict(record, cutoff, plain_theta)
            use = kept[rows] & ~resent(record)[rows]
            rows, values = rows[use], values[use]
            squares = squares + np.sum((record.tau[rows] - values) ** 2, axis=0)
            plain_squares = plain_squares + np.sum((record.tau[rows] - predicted[rows]) ** 2, axis=0)
            count += rows.shape[0]
        else:
            mse[label] = squares / count
            mse[f"plain OLS ({label}'s samples)"] = plain_squares / count
    return {"mse": mse, "exits": exits, "cutoff": cutoff, "floor": (NOISE * spread) ** 2, "effects": selected}


UR10E_LOG = Log(10.0, 500.0, motion_hz=0.1)
KINDS = (
    Kind("UR10e-like, Fourier train/validate (10 s at 500 Hz, logged dq), point-to-point test with rests",
         dh_urdf(ur10e), UR10E_LOG, UR10E_LOG, Log(12.0, 500.0), test_motion="point-to-point", slow=True),
    Kind("Schunk LWA 4P-like, 15 x 3.7 s training, 5 validation, 6 test records at 100 Hz, no dq",
         dh_urdf(lwa4p), *(Log(3.7, 100.0, velocity=False, motion_hz=0.27),) * 3, records=(15, 5, 6), slow=True),
    Kind("KR300-like heavy arm, 10 s / 10 s / 10 s at 250 Hz, no dq, slow motion, large Coulomb friction",
         dh_urdf(kr300), *(Log(10.0, 250.0, velocity=False, motion_hz=0.08),) * 3,
         coulomb=(500.0, 1200.0, 600.0, 70.0, 120.0, 8.0), viscous=(800.0, 1500.0, 800.0, 80.0, 120.0, 8.0),
         slow=True),
    Kind("continuous joints (no limit on one), fixed mount, camera, flange and tool; 8 s / 3 s / 5 s at 200 Hz",
         text_urdf(CONTINUOUS_ARM), Log(8.0, 200.0), Log(3.0, 200.0), Log(5.0, 200.0), motion_limits=CONTINUOUS_MOTION),
    Kind("puma 3 joints: torque sensor offset (30 % of spread), quantised torques, columns shuffled among others",
         builtin("puma560", 3), Log(8.0, 250.0, velocity=False), Log(3.0, 250.0, velocity=False),
         Log(5.0, 250.0, velocity=False), torque_bias=0.3, torque_quantum=0.03, columns="shuffled"),
)


def marks(kind: Kind) -> list[pytest.MarkDecorator]:
    chosen = [pytest.mark.slow] if kind.slow else []
    if kind.xfail:
        chosen.append(pytest.mark.xfail(strict=True, reason=kind.xfail))
    return chosen


@pytest.mark.parametrize("kind", [pytest.param(kind, id=kind.name, marks=marks(kind)) for kind in KINDS])
def test_the_defaults_run_and_predict_another_kind_of_robot_as_well_as_a_plain_fit(kind, tmp_path):
    as_well_as_the_plain_fit(kind.name, run_kind(kind, tmp_path))


def named_law(effect: str) -> str:
    """The law an effect named ``SPEC on CHANNEL`` is: a shaped variant counts as its law (``coulomb:tanh`` is a
    Coulomb law), a law differing by direction does not (``viscous:direction`` is a law the symmetric truth of
    these cases does not hold)."""
    spec = effect.split(" on ")[0]
    return spec if spec.endswith(":direction") else spec.split(":")[0]


def as_well_as_the_plain_fit(name: str, outcome: dict, chosen: str = "",
                             verbs: tuple[str, ...] = ("default", "diagnose")) -> None:
    """Print each verb's test MSE per joint against the plain fit's on its samples, then check that no verb exited
    and each of ``verbs`` is within the noise floor's allowance of the plain fit, per joint and in total."""
    mse, floor = outcome["mse"], outcome["floor"]
    print(f"\n{name}: plain cut-off {outcome['cutoff']} Hz; effects {outcome['effects']}; {chosen}" + "; ".join(
        f"{label} {(mse[label] / mse[f'plain OLS ({label}' + chr(39) + 's samples)']).round(3).tolist()} total "
        f"{mse[label].sum() / mse[f'plain OLS ({label}' + chr(39) + 's samples)'].sum():.3f}"
        for label in ("default", "diagnose") if label in mse))
    assert not outcome["exits"], outcome["exits"]
    for label in verbs:
        plain = mse[f"plain OLS ({label}'s samples)"]
        assert np.all(within(mse[label], plain, floor, PER_JOINT)), (label, (mse[label] / plain).round(3))
        assert within(mse[label].sum(), plain.sum(), floor.sum(), TOTAL), (label, mse[label].sum() / plain.sum())


def test_the_filter_candidates_reach_the_limit_the_candidates_respect():
    """A record at 100 Hz (the Schunk-like case): a filter at 0.4 of the rate, the rule's own ceiling (0.8 x
    Nyquist), is a candidate (the fit's Coulomb friction is biased low as the cut-off falls, and the validation
    error with it), none above it."""
    from dynamics.measurements import Measurements
    from estimation.identification.preprocessing_choice import candidates
    from estimation.preprocessing.plan import Preprocessing

    t = np.arange(0.0, 3.7, 0.01)
    q = np.column_stack([np.sin(2 * PI * 0.27 * t), np.cos(2 * PI * 0.54 * t)])
    record = Measurements(t, q, None, None, np.zeros_like(q), None, {})
    found = candidates([record], Preprocessing("butterworth", cutoff_hz=10.0), None, ("butterworth",),
                       held_out=[record])
    cutoffs = sorted(plan.cutoff_hz for plan in found if plan.method == "butterworth")
    assert max(cutoffs) == pytest.approx(40.0) and 25.0 in cutoffs, cutoffs
