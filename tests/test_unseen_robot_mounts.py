"""Robots and logs the project has not seen (issue 34), beside the other unseen-robot modules
(:mod:`tests.test_unseen_robots`, ``_kinds``, ``_realities``, ``_labs``, ``_logs``, ``_cells``), run by the same
verbs and plain fit (:func:`tests.test_unseen_robot_labs.verbs_against_the_plain_fit`) (h-unseen8):

- an arm mounted on a wall or on the ceiling: the URDF's fixed ``world -> base_link`` joint rotated, so gravity is
  not along the base's ``-z``; and the same arm whose URDF holds no mount (gravity assumed along the base's ``-z``);
- a pedestal that is not level (5° off the vertical), the URDF level;
- friction that falls as the gearboxes warm up (viscous and Coulomb 30 % lower after a few minutes): training cold,
  validation later, the test warm;
- a geared arm's reflected rotor inertia (armature, ``I_a ddq`` on each joint) that the URDF does not hold;
- one joint's torque logged with the opposite sign convention (in every record);
- a training log concatenated from two sessions: the clock restarting at zero in the middle of the file, or jumping
  forward by minutes.

No data are copied; every record is simulated (the plain fit's model class, :func:`tests.test_unseen_robots.truth`,
plus each case's effect, white torque noise of 2 % of each channel's spread). Each case runs the default
``oed identify`` (told the plain fit's model class) and ``oed diagnose`` (its own defaults), then ``oed predict`` on a
test record no choice saw, against the plain Pinocchio least-squares fit of ``benchmarks/bench_real_robots.py`` (its
cut-off chosen on the validation record, given the same description) on the same recorded samples: per joint within
1.3x, in total at most 1.0x, each figure allowed its noise floor's sampling spread; and ``oed predict`` on the
validation record reproduces the validation error each verb reported (relative 1e-6)."""

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

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.urdf_export import robot_urdf
from oed.fourier import random_fourier
from tests.conftest import shared_data
from tests.test_one_answer_audit import RELATIVE
from tests.test_unseen_robot_kinds import as_well_as_the_plain_fit, marks, plain_fit
from tests.test_unseen_robot_labs import puma, verbs_against_the_plain_fit
from tests.test_unseen_robots import FRICTION, NOISE, Log, logged, times, truth

PI = np.pi

#: the mounts: the rotation (roll, pitch, yaw) of the fixed joint ``world -> base_link``
MOUNTS = {"floor": (0.0, 0.0, 0.0), "wall": (0.0, PI / 2, 0.0), "ceiling": (PI, 0.0, 0.0),
          "tilted": (0.0, np.radians(5.0), 0.0)}
#: when each role's record starts after the robot is switched on (s): training cold, the test warm
STARTS = {"train": 0.0, "validate": 120.0, "test": 600.0}
#: a PUMA 560's reflected rotor inertias (kg m²), joints 1-6 (Armstrong, Khatib and Burdick 1986, Table A4)
PUMA_ARMATURE = (1.14, 4.71, 0.83, 0.2, 0.179, 0.193)


@dataclass(frozen=True)
class Mounted:
    """One case: the robot (its true bodies), the logs of each role and what the lab's robot and logger hold
    beyond the plain class."""

    name: str
    robot: Callable[[], object]
    train: Log
    validate: Log
    test: Log
    mount: str = "floor"  # the truth's mount (:data:`MOUNTS`)
    described: str = "floor"  # the mount the URDF given to the verbs (and the plain fit) holds
    warming: float = 0.0  # the share of viscous and Coulomb friction lost once warm (:func:`warm`)
    armature: tuple[float, ...] = ()  # the reflected rotor inertia of each joint, not in the URDF
    flipped: int = 0  # a joint (1-based) whose torque is logged with the opposite sign
    sessions: str = ""  # the training record two sessions: "restart" (t from 0 again) or "jump" (3 min later)
    said: str = ""  # a pattern one of `oed identify`'s warnings must match (what the user is told to do)
    slow: bool = False
    xfail: str = ""


def rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF's ``rpy``: ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


def mounted_urdf(robot, mount: str) -> str:
    """The robot's URDF, its ``base_link`` hung from a ``world`` link on a fixed joint rotated by the mount (none
    for ``floor``: the base frame is the world's)."""
    text = robot_urdf(robot)
    if mount == "floor":
        return text
    rpy = " ".join(f"{value:.17g}" for value in MOUNTS[mount])
    fixture = (f'<link name="world" />\n  <joint name="mount" type="fixed"><origin xyz="0.3 -0.2 1.5" rpy="{rpy}" />'
               '<parent link="world" /><child link="base_link" /></joint>\n  <link name="base_link" />')
    return text.replace('<link name="base_link" />', fixture, 1)


def gravity_in_base(mount: str) -> np.ndarray:
    """Gravity in the base frame of a robot on ``mount``."""
    return rotation(*MOUNTS[mount]).T @ np.array([0.0, 0.0, -9.81])


def warm(t_on: np.ndarray, share: float, minutes: float = 2.0) -> np.ndarray:
    """The friction's scale at ``t_on`` s after switching on: ``1 − share (1 − exp(−t/T))``, ``T`` = ``minutes``."""
    return 1.0 - share * (1.0 - np.exp(-t_on / (60.0 * minutes)))


def motion(limits, seed: int, t: np.ndarray, hz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return random_fourier(limits, seed=seed, frequency_hz=hz).evaluate(t - t[0])


def write_records(case: Mounted, folder: Path) -> tuple[Path, dict, dict, np.ndarray]:
    """The description and the records of each role as the lab's logger writes them: ``(urdf, records, files,
    spread)``; the plain fit's training records are a list (the sessions apart, as a user would split them)."""
    from benchmarks.bench_real_robots import Record

    robot = case.robot()
    urdf = folder / "robot.urdf"
    urdf.write_text(mounted_urdf(robot, case.described))
    truth_model = build_model(robot.with_gravity(gravity_in_base(case.mount)), "internal", FRICTION)
    theta = truth(build_model(robot, "internal", FRICTION))  # the true bodies, ±20 %: whatever the mount
    names = list(truth_model.parameter_names)
    n = robot.n_joints
    fv = np.array([theta[names.index(f"fv{j + 1}")] for j in range(n)])
    fc = np.array([theta[names.index(f"fc{j + 1}")] for j in range(n)])
    limits = SimpleNamespace(n_joints=n, lower=np.asarray(robot.lower, float), upper=np.asarray(robot.upper, float),
                             velocity_limit=np.asarray(robot.velocity_limit, float))
    spread, records, files = None, {}, {}
    for role, log, seed in (("train", case.train, 11), ("validate", case.validate, 12), ("test", case.test, 13)):
        generator = np.random.default_rng(1000 + seed)
        t = times(log, generator)
        parts = [(t, seed)]
        if role == "train" and case.sessions:  # two sessions of half the length, another motion each
            half = t[t < 0.5 * log.seconds]
            parts = [(half, seed), (half, seed + 10)]
        tables, pieces = [], []
        for index, (stamps, motion_seed) in enumerate(parts):
            q, dq, ddq = motion(limits, motion_seed, stamps, log.motion_hz)
            tau = truth_model.predict(theta, q, dq, ddq)
            if case.warming:
                on = stamps - stamps[0] + STARTS[role] + 60.0 * index
                tau = tau - (1.0 - warm(on, case.warming))[:, None] * (fv * dq + fc * np.sign(dq))
            if case.armature:
                tau = tau + np.asarray(case.armature) * ddq
            if spread is None:
                spread = tau.std(axis=0)
            tau = tau + generator.normal(0.0, 1.0, tau.shape) * NOISE * spread
            if case.flipped:
                tau[:, case.flipped - 1] *= -1.0
            stamps, q, dq, tau, frame = logged(stamps.copy(), q, dq, tau, log, generator)
            pieces.append(Record(stamps, q, tau, dq if log.velocity else None))
            table = pd.DataFrame(frame)
            if index == 1:  # the second session's clock: from zero again, or three minutes after the first's end
                table["t"] = table["t"] + (0.0 if case.sessions == "restart" else parts[0][0][-1] + 180.0)
            tables.append(table)
        files[role] = folder / f"{role}.csv"
        pd.concat(tables, ignore_index=True).to_csv(files[role], index=False, float_format="%.10g")
        records[role] = pieces if role == "train" else pieces[0]
    return urdf, records, files, spread


def run_mounted(case: Mounted, folder: Path) -> dict:
    """Write the records, run the verbs and the plain fit: per joint test MSE of each on the same samples, and
    whether ``oed predict`` reproduces each verb's reported validation error."""
    from benchmarks.bench_real_robots import PlainFit

    urdf, records, files, spread = write_records(case, folder)
    plain = PlainFit(["--urdf", str(urdf)])
    cutoff, plain_theta = plain_fit(plain, records["train"], [records["validate"]], case.train.rate_hz)
    predicted_plain, kept = plain.predict(records["test"], cutoff, plain_theta)
    outcome = verbs_against_the_plain_fit(urdf, files, records["test"], kept, predicted_plain, folder)
    return {**outcome, "cutoff": cutoff, "floor": (NOISE * spread) ** 2}


def six(seconds: tuple[float, float, float] = (10.0, 4.0, 6.0), rate: float = 250.0) -> tuple[Log, Log, Log]:
    return tuple(Log(duration, rate, velocity=False) for duration in seconds)


CASES = (
    Mounted("PUMA 6 joints on a wall (the URDF's world->base_link joint pitched 90°), 10 s / 4 s / 6 s at 250 Hz, "
            "no dq", puma(6), *six(), mount="wall", described="wall", slow=True),
    Mounted("PUMA 3 joints on the ceiling (the URDF's world->base_link joint rolled 180°), 8 s / 3 s / 5 s at "
            "250 Hz, no dq", puma(3), *six((8.0, 3.0, 5.0)), mount="ceiling", described="ceiling"),
    # both verbs and the plain fit predict joint 1 at 4500x the noise floor (the ratios pass: 1.02 and 0.016 of the
    # plain fit), and diagnose names a spring on joint 1 where gravity acts; identify now says the mount to write
    Mounted("PUMA 6 joints on a wall, the URDF without the mount (gravity taken along the base's -z)", puma(6), *six(),
            mount="wall", described="floor", said=r'rpy="[-.\d]+ 1\.5\d+ 0\.0000"', slow=True),
    Mounted("PUMA 6 joints on a pedestal 5° off level, the URDF level", puma(6), *six(), mount="tilted",
            described="floor", slow=True),
    Mounted("PUMA 6 joints, friction 30 % lower once warm (T = 2 min): training cold, validation at 2 min, test at "
            "10 min", puma(6), *six(), warming=0.3, slow=True,
            xfail="identify 0.979/1.123/1.072/1.057/1.002/1.023 of the plain fit, 1.034 in total; diagnose 1.026 "
                  "(joint 2 1.136); every model 11-170x the noise floor: no model of either side holds friction that "
                  "changes with the temperature. The toolkit fits the training record's cold friction (fc1..6 0.986, "
                  "1.389, 1.770, 2.212, 2.572, 2.960 against the truth's 1.0-3.0, torques fitted as recorded), the "
                  "plain fit 14-21 % lower (0.792 ... 2.592: its filtered torques smear the Coulomb steps, h-unseen3), "
                  "which is nearer the warm test's (0.70 of cold): the plain fit wins by its bias. Both verbs say the "
                  "drift (friction_drift: scale 0.817-0.824 ± 0.007 on every joint, truth 0.820). The answer keeps "
                  "the training record's friction: with the validation record's friction it would predict this test "
                  "at 0.153 (diagnose 0.192) of the plain fit, but with the records' order reversed (validation cold, "
                  "training at 2 min) at 7.6x, and the pooled friction at 0.70 and 2.25x: which record is nearer the "
                  "use the records do not say (h-drift)"),
    Mounted("PUMA 6 joints, the reflected rotor inertias (armature) not in the URDF", puma(6), *six(),
            armature=PUMA_ARMATURE, slow=True),
    # both verbs run within the margins (identify 0.375 of the plain fit in total, diagnose 0.893) but joint 2 stays
    # 89x and 215x its noise floor: the joint-direction check says the convention and the file that declares it
    Mounted("PUMA 3 joints, joint 2's torque logged with the opposite sign", puma(3), *six((8.0, 3.0, 5.0)),
            flipped=2, said=r'"torque_signs": \{"joint2": -1\}', slow=True),
    Mounted("PUMA 3 joints, the training log two sessions, the clock restarting at zero in the middle", puma(3),
            *six((10.0, 3.0, 5.0)), sessions="restart", slow=True),
    Mounted("PUMA 3 joints, the training log two sessions, the clock jumping 3 minutes forward in the middle",
            puma(3), *six((10.0, 3.0, 5.0)), sessions="jump", slow=True),
)


@pytest.mark.parametrize("case", [pytest.param(case, id=case.name, marks=marks(case)) for case in CASES])
def test_the_defaults_run_and_predict_a_mounted_or_warming_robot_as_well_as_a_plain_fit(case, tmp_path):
    outcome = run_mounted(case, tmp_path)
    print(f"\nreproduced validation error (relative): {outcome['reproduced']}; floor {outcome['floor'].round(5)}; "
          f"mse {({label: values.round(5).tolist() for label, values in outcome['mse'].items()})}")
    for label in ("default", "diagnose"):  # the friction drift said where friction drifts, and nowhere else
        document = json.loads((tmp_path / f"{label}.json").read_text())
        said = document["warnings"] if isinstance(document["warnings"], list) else document["warnings"]["after"]
        drifted = [text for text in said if text.startswith("friction differs")]
        marked = {name for name, joint in document["friction_drift"]["joints"].items() if joint["marked"]}
        assert bool(drifted) == bool(marked) == bool(case.warming), (label, drifted, document["friction_drift"])
        if case.warming:  # every joint, at the scale the truth gives (the mean over each record's samples)
            expected = np.mean(warm(STARTS["validate"] + np.arange(0.0, 4.0, 0.004), case.warming)) / np.mean(
                warm(STARTS["train"] + np.arange(0.0, 10.0, 0.004), case.warming))
            scales = [joint["scale"] for joint in document["friction_drift"]["joints"].values()]
            assert len(marked) == 6 and np.allclose(scales, expected, atol=0.02), (scales, expected)
    as_well_as_the_plain_fit(case.name, outcome, f"chosen {outcome['selections']}; ")
    for label, error in outcome["reproduced"].items():
        assert error < RELATIVE, (label, error)
    said = json.loads((tmp_path / "default.json").read_text())["warnings"]
    mounts = [text for text in said if "gravity load points elsewhere" in text]
    assert bool(mounts) == (case.mount != case.described), mounts
    if case.said:
        assert any(re.search(case.said, text) for text in said), said
    # `oed diagnose` checks the mount too (h-mountdiag): said where the URDF lacks it, nowhere else (not for a
    # reversed torque either), and no spring where the turned gravity acts (before, a spring on tau1: 57 N m/rad on
    # the wall, 5 on the 5° pedestal)
    diagnosed = json.loads((tmp_path / "diagnose.json").read_text())
    said = [text for part in diagnosed["warnings"].values() for text in part]
    mounts = [text for text in said if "gravity load points elsewhere" in text]
    assert bool(mounts) == (case.mount != case.described), mounts
    if mounts:
        # the found gravity a candidate of both verbs' answers (h-gravity): taken here, it is the result files'
        # gravity, within 2° of the truth's; the diagnosis with it names no spring either (it tried every law)
        for label, document in (("default", json.loads((tmp_path / "default.json").read_text())),
                                ("diagnose", diagnosed)):
            gravity, truth_gravity = np.array(document["model_file"]["gravity"]), gravity_in_base(case.mount)
            angle = np.degrees(np.arccos(np.clip(gravity @ truth_gravity / (np.linalg.norm(gravity)
                                                                             * np.linalg.norm(truth_gravity)), -1, 1)))
            assert angle < 2.0, (label, gravity, truth_gravity)
            assert "the gravity the mount check found" in document["model_selection"]["reason"], label
        assert "the answer is fitted with the found gravity" in mounts[0], mounts
        assert not [effect for effect in diagnosed["effects"] if effect["name"] == "spring" and "tau1" in effect["channels"]]
    else:  # the description's: the URDF's robot as loaded (a mount in it turns the chain, not gravity)
        described = load_robot(urdf=tmp_path / "robot.urdf").gravity
        for label in ("default", "diagnose"):
            gravity = json.loads((tmp_path / f"{label}.json").read_text())["model_file"]["gravity"]
            assert np.allclose(gravity, described), (label, gravity, described)


def test_a_mount_in_the_urdf_turns_gravity_as_pinocchio_does(tmp_path):
    """The toolkit's model of a URDF whose ``world -> base_link`` joint is rotated predicts the torques of the robot
    whose gravity is turned into the base frame, as Pinocchio does on that file (wall, ceiling, a tilt)."""
    import pinocchio as pin

    robot = load_robot("puma560", joints=6)
    generator = np.random.default_rng(0)
    q, dq, ddq = (generator.uniform(-1.0, 1.0, (5, 6)) for _ in range(3))
    for mount in ("wall", "ceiling", "tilted"):
        path = tmp_path / f"{mount}.urdf"
        path.write_text(mounted_urdf(robot, mount))
        read = build_model(load_robot(urdf=path), "internal", "")
        turned = build_model(robot.with_gravity(gravity_in_base(mount)), "internal", "")
        theta = turned.robot.standard_parameters
        reference = pin.buildModelFromUrdf(str(path))
        data = reference.createData()
        expected = np.array([pin.rnea(reference, data, *state) for state in zip(q, dq, ddq)])
        assert np.allclose(turned.predict(theta, q, dq, ddq), expected, atol=1e-8), mount
        assert np.allclose(read.predict(read.robot.standard_parameters, q, dq, ddq), expected, atol=1e-8), mount


def test_a_clock_that_starts_again_splits_the_record_in_memory_and_streamed(tmp_path):
    """Two sessions logged into one file, the clock from zero again (or from any earlier time, more than ``max_gap``
    back): read as two segments, each with its own time stamps as recorded, said in a :class:`SplitWarning`, in
    memory and by the streamed reader's segments alike; a small step back (two rows out of order) stays the error
    naming it, and :func:`read_measurements` (one segment) still refuses the restart naming the segments."""
    from estimation.data import TimeBaseError
    from estimation.data.loading import SplitWarning
    from estimation.data.records import read_measurements, read_record
    from estimation.streaming.chunks import segment_sources
    from tests.test_unseen_robots import urdf_of, write_record

    urdf = urdf_of("puma560:3", tmp_path)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    write_record(model, truth(model), Log(2.0, 250.0, velocity=False), 11, tmp_path / "clean.csv")
    table = pd.read_csv(tmp_path / "clean.csv")
    table.loc[300:, "t"] -= table["t"].iloc[300] - 0.5  # the second session's clock from 0.5 s
    table.to_csv(tmp_path / "sessions.csv", index=False)
    with pytest.warns(SplitWarning, match=r"clock starts again at row\(s\) 300 \(t = 1\.196 -> 0\.5 s\).*2 segments"):
        first, second = read_record(tmp_path / "sessions.csv", model=model)
    assert np.array_equal(first.t, table["t"].to_numpy()[:300])
    assert np.array_equal(second.t, table["t"].to_numpy()[300:])
    assert np.array_equal(second.tau, table[["tau1", "tau2", "tau3"]].to_numpy()[300:])
    streamed = segment_sources([tmp_path / "sessions.csv"], model, chunk_size=250)  # (said when each is read)
    assert [str(path) for path in streamed] == [f"{tmp_path / 'sessions.csv'} (segment {k})" for k in (1, 2)]
    with pytest.raises(TimeBaseError, match="clock restarted"):
        read_measurements(tmp_path / "sessions.csv", model=model)
    swapped = pd.read_csv(tmp_path / "clean.csv")
    swapped.iloc[[100, 101]] = swapped.iloc[[101, 100]].to_numpy()
    swapped.to_csv(tmp_path / "swapped.csv", index=False)
    with pytest.raises(TimeBaseError, match="decreases at row 101"):
        read_record(tmp_path / "swapped.csv", model=model)


def mount_records(mount: str, flipped: int | None = None) -> tuple[object, list]:
    """A PUMA 6 on ``mount`` with a description on the floor, 10 s of training and 4 s of validation (exact
    derivatives, 2 % torque noise; ``flipped``: a joint, 0-based, whose torque is logged with the opposite sign):
    the described model (the plain class) and the two records."""
    from dynamics.measurements import Measurements

    robot = load_robot("puma560", joints=6)
    model = build_model(robot, "internal", FRICTION)
    truth_model = build_model(robot.with_gravity(gravity_in_base(mount)), "internal", FRICTION)
    theta = truth(model)
    records = []
    for seed, seconds in ((11, 10.0), (12, 4.0)):
        t = np.arange(0.0, seconds, 0.004)
        q, dq, ddq = random_fourier(robot, seed=seed, frequency_hz=0.2).evaluate(t)
        tau = truth_model.predict(theta, q, dq, ddq)
        tau = tau + np.random.default_rng(seed).normal(0.0, 1.0, tau.shape) * NOISE * tau.std(axis=0)
        if flipped is not None:
            tau[:, flipped] *= -1.0
        records.append(Measurements(t, q, dq, ddq, tau, None, {}))
    return model, records


@pytest.mark.parametrize("mount", ["floor", "wall", pytest.param("ceiling", marks=pytest.mark.slow),
                                   pytest.param("tilted", marks=pytest.mark.slow)])
def test_the_mount_check_finds_gravity_where_the_torques_put_it(mount):
    """A PUMA 6 on ``mount`` with a description on the floor (exact derivatives, 2 % torque noise): the check finds
    gravity in the base frame within 2° of the truth, and marks it unless the robot stands on the floor (a 5° tilt
    too: the gravity loads it leaves out stay far above the noise)."""
    from estimation.identification.mount import check_mount, mount_rpy

    model, records = mount_records(mount)
    check = check_mount(model, *records)
    expected = gravity_in_base(mount)
    found = np.degrees(np.arccos(np.clip(check.found @ expected / 9.81**2, -1.0, 1.0)))
    print(f"\n{mount}: found {check.found.round(3)}, {found:.2f}° off; MSE {check.found_mse:.4g} against "
          f"{check.declared_mse:.4g} declared")
    assert found < 2.0 and check.marked == (mount != "floor")
    if mount != "floor":
        assert "rpy=" in check.message()
        turned = rotation(*mount_rpy(check.found)).T @ np.array([0.0, 0.0, -9.81])
        assert np.allclose(turned, check.found, atol=1e-9)


def test_the_mount_check_says_nothing_the_descriptions_bodies_contradict():
    """The real KUKA LWR4+ stands on the floor. Before the check was batched (h-mountdiag), its least-squares fit
    preferred gravity turned 179° on the validation run (a repeat of the training motion) with half the error, and it
    told the user to mount the arm on the ceiling, which the description's own bodies, turned so, contradict (h-newuser).
    Now the fit prefers a 2.5° tilt (half the error again, joint 1's load as an offset would be), which makes joint 6
    worse: neither is said. The description's bodies' errors with either gravity are the model's own (recomputed here
    by the model built with that gravity, not from the check's sums)."""
    from estimation.datasets.kuka import load_kuka_run
    from estimation.identification.mount import MountCheck, check_mount

    folder = shared_data("kuka_lwr4")
    robot = load_robot(urdf=folder / "kuka_lwr4.urdf")
    model = build_model(robot, "internal", "viscous")
    train, validation = (load_kuka_run(folder / f"kuka_lwr4_HW_measurements_{index}.npz") for index in (1, 2))
    check = check_mount(model, train, validation)
    theta = model.nominal_parameters()
    upright, turned = (build_model(robot.with_gravity(gravity), "internal", "viscous").predict(
        theta, validation.q, validation.dq, validation.ddq) for gravity in (check.declared, check.found))
    upright_mse, turned_mse = (float(((tau - validation.tau) ** 2).mean(axis=0).sum()) for tau in (upright, turned))
    assert np.isclose(check.nominal_found_mse / check.nominal_declared_mse, turned_mse / upright_mse, rtol=0.1)
    assert not check.marked
    # the bodies' word alone: the same figures as a marked check's, but the description's bodies predict worse turned
    said = MountCheck(np.array([0.0, 0.0, -9.81]), np.array([0.0, 0.0, 9.81]), 1.0, 0.4)
    assert said.marked
    assert not MountCheck(said.declared, said.found, 1.0, 0.4, nominal_declared_mse=1.0, nominal_found_mse=34.0).marked


@pytest.mark.slow
def test_the_armature_candidate_is_taken_alike_in_memory_and_streamed(tmp_path):
    """The armature case's records: the default ``oed identify`` takes the armature (said in the reason) in memory and
    streamed (``--chunk-size``) alike, the same answer and validation errors (relative 1e-6)."""
    from tests.test_unseen_robot_kinds import quiet

    case = next(case for case in CASES if case.armature)
    urdf, _, files, _ = write_records(case, tmp_path)
    documents = []
    for label, more in (("memory", []), ("streamed", ["--chunk-size", "1000"])):
        out = tmp_path / f"{label}.json"
        code, message = quiet(["identify", "--urdf", str(urdf), "--data", str(files["train"]), "--validate",
                               str(files["validate"]), "--friction", FRICTION, *more, "--out", str(out)])
        assert code == 0, message
        documents.append(json.loads(out.read_text()))
    memory, streamed = documents
    assert "armature" in memory["effects"] and memory["effects"] == streamed["effects"]
    assert "the rotors' reflected inertia" in memory["model_selection"]["reason"] and "taken" in memory["model_selection"]["reason"]
    assert memory["chosen"] == streamed["chosen"]
    np.testing.assert_allclose(list(streamed["validation"]["mse"].values()), list(memory["validation"]["mse"].values()),
                               rtol=1e-6)


def test_a_reversed_torque_is_not_said_to_be_a_mount():
    """A PUMA 6 on the floor whose joint 2 torque is logged with the opposite sign: another direction of gravity
    lowers the total validation error (it serves joint 2), but makes another joint's worse: a turned gravity is the
    whole robot's, so the check does not mark it (h-mountdiag: before, `oed diagnose` said a mount 171° off), while
    the wall's found gravity explains every joint (:meth:`MountCheck.explained_channels`)."""
    from estimation.identification.mount import WORSE_LIMIT, check_mount

    for mount, flipped in (("floor", 1), ("wall", None)):
        model, records = mount_records(mount, flipped)
        check = check_mount(model, *records)
        ratios = np.array(check.found_channel_mse) / np.array(check.declared_channel_mse)
        print(f"\n{mount}, torque {flipped} reversed: total {check.found_mse / check.declared_mse:.3f}, "
              f"channels {ratios.round(3)}")
        if flipped is not None:
            assert check.found_mse < check.declared_mse and ratios.max() > WORSE_LIMIT
            assert not check.marked and check.explained_channels() == ()
        else:
            assert check.marked and check.explained_channels() == tuple(range(6))
