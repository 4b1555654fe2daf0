"""What a real lab's logs have that the project's other unseen robots do not (issue 34), beside
:mod:`tests.test_unseen_robots`, :mod:`tests.test_unseen_robot_kinds` and :mod:`tests.test_unseen_robot_realities`:

- a gear-driven arm whose Coulomb friction changes with the position (an eccentric gear: ±50 % over a turn);
- springs that the description does not hold: a cable harness twisted about the base's vertical axis (no gravity
  term can absorb it) and a gas spring holding the shoulder up;
- a description whose inertials are badly wrong (CAD without motors: masses halved, first moments at 35 %,
  inertias halved), so the prior the consistent candidate pulls toward misleads;
- torques logged in motor units, each joint's its own unknown gain (a current times a constant nobody gave), or
  one constant for all;
- a log with dropouts (rows whose values are blank) and duplicated time stamps (a logger writing a row twice);
- Fourier training and validation, then a slow teach-pendant motion (one joint jogged at a time, ramps and rests);
- a 6-joint arm logged at 100 Hz with coarse (12-bit) encoders and no velocity;
- records of different rates and lengths for the three roles (training at 1 kHz with a logged velocity, validation
  at 250 Hz and test at 100 Hz without).

No data are copied; every record is simulated here: the plain fit's model class
(:func:`tests.test_unseen_robots.truth`), plus each case's effect, white torque noise of 2 % of each channel's
spread, the loggers of :func:`tests.test_unseen_robots.logged`.

Each case runs the default ``oed identify`` (told the plain fit's model class) and ``oed diagnose`` (its own
defaults), then ``oed predict`` on the test record that no choice saw, against the plain Pinocchio least-squares
fit of ``benchmarks/bench_real_robots.py`` (its cut-off chosen on the validation record), on the same recorded
samples: per joint within 1.3x, in total at most 1.0x, each figure allowed its noise floor's sampling spread; and
``oed predict`` on the validation record reproduces the validation error each verb reported (relative 1e-6).

Beside, small and fast: dropouts read alike in memory and streamed; ``oed predict`` on a record logged at a lower
rate than the model's filter allows; records without the logged ``dq``/``ddq`` the training record has."""

from __future__ import annotations

import json
import warnings
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
from tests.test_one_answer_audit import RELATIVE, relative, reported_models
from tests.test_unseen_robot_kinds import as_well_as_the_plain_fit, marks, minimum_jerk, point_to_point, quiet, ur10e
from tests.test_unseen_robot_realities import named_and_chosen, scored_on_test
from tests.test_unseen_robots import FRICTION, NOISE, Log, logged, times, truth

PI = np.pi


def puma(joints: int) -> Callable[[], object]:
    return lambda: load_robot("puma560", joints=joints)


@dataclass(frozen=True)
class Lab:
    """One case: the robot (its true bodies), the log of each role, the test record's motion, the truth's effect
    beyond the plain class, and what the lab's description and logger get wrong."""

    name: str
    robot: Callable[[], object]
    train: Log
    validate: Log
    test: Log
    test_motion: str | Callable[[SimpleNamespace, int, np.ndarray], tuple[np.ndarray, ...]] = "fourier"
    # "point-to-point", "jog" (a teach pendant's slow moves, one joint at a time), or a motion of its own
    # ``(limits, seed, t) -> (q, dq, ddq)``
    validate_motion: str = "fourier"  # the validation record's: "fourier" (the training's kind) or "point-to-point"
    rest: float = 0.4  # the rests between point-to-point moves (s)
    armature: tuple[float, ...] = ()  # each joint's reflected rotor inertia (kg m²), not in the description
    extra: str | Callable[[np.ndarray, np.ndarray], np.ndarray] = ""  # "position coulomb", "spring", or a law
    # ``(q, dq) -> torque`` of its own (joint side, the samples in time order)
    sensed: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None  # what the torque sensor reads of the
    # true torque ``(tau, spread) -> tau`` (before its white noise), e.g. a sensor's hysteresis
    wrong_bodies: bool = False  # the description's inertials: CAD without motors
    gains: tuple[float, ...] = ()  # torques logged in motor units: tau_j / gain_j
    dropouts: int = 0  # rows whose values are blank (the time stamp kept)
    duplicates: int = 0  # rows written twice (the same time stamp, the same values)
    halted: float = 0.0  # the share at rest, in its middle, of the records of ``halted_in`` (:func:`halt`)
    halted_in: tuple[str, ...] = ("train",)
    drift: float = 0.0  # a torque sensor's bias warming up (:func:`warming`), of each channel's spread
    friction_scale: tuple[float, ...] = ()  # each joint's true friction and offset scaled (a light wrist's small)
    equal_noise: bool = False  # the torque sensors' noise alike on every joint (2 % of the channels' mean spread)
    trained_range: tuple[int, float] = ()  # (joint, share): training and validation confined to that share of the
    # joint's range from its lower limit, the test record over the whole range
    slow: bool = False
    xfail: str = ""


def cad_without_motors(robot) -> object:
    """The description a CAD export without the motors gives: each link's mass halved, its first moment at 35 %
    (the centre of mass moved to 70 % of its distance from the joint) and its inertia about the joint halved
    (still physically consistent: the inertia about the centre of mass stays positive)."""
    scale = np.tile(np.r_[0.5, 0.35, 0.35, 0.35, np.full(6, 0.5)], robot.n_joints)
    return robot.with_parameters(robot.standard_parameters * scale)


def jog(limits, seed: int, t: np.ndarray, speed: float = 0.1, rest: float = 0.5) -> tuple[np.ndarray, ...]:
    """A teach pendant's motion: one joint at a time (in a random order) jogged at ``speed`` of its speed limit to
    a random pose (within 40 % of its half range about the centre), with minimum-jerk ramps of 0.3 s and a rest
    after each move; the other joints still."""
    generator = np.random.default_rng(seed)
    centre, half = 0.5 * (limits.lower + limits.upper), 0.5 * (limits.upper - limits.lower)
    n = limits.n_joints
    q, dq, ddq = np.tile(centre, (t.shape[0], 1)), np.zeros((t.shape[0], n)), np.zeros((t.shape[0], n))
    pose, clock = centre.copy(), t[0] + rest
    while clock < t[-1]:
        joint = int(generator.integers(n))
        target = centre[joint] + generator.uniform(-0.4, 0.4) * half[joint]
        step = target - pose[joint]
        duration = max(0.6, 1.875 * abs(step) / (speed * limits.velocity_limit[joint]))
        s = np.clip((t - clock) / duration, 0.0, 1.0)
        inside = (t > clock) & (t < clock + duration)
        position, velocity, acceleration = minimum_jerk(s)
        q[t >= clock, joint] = pose[joint] + position[t >= clock] * step
        dq[inside, joint] = velocity[inside] * step / duration
        ddq[inside, joint] = acceleration[inside] * step / duration**2
        pose[joint], clock = target, clock + duration + rest
    return q, dq, ddq


def halt(motion, t: np.ndarray, share: float, ramp: float = 0.5) -> tuple[np.ndarray, ...]:
    """``motion`` (an object with ``evaluate(t) -> (q, dq, ddq)``) stopped for ``share`` of the record in its middle:
    its own time ``τ(t)`` slows to rest in ``ramp`` seconds (``τ' = 1 − s³(10 − 15 s + 6 s²)``), stays, and speeds
    up again alike; ``q = f(τ)``, ``dq = f'(τ) τ'``, ``ddq = f''(τ) τ'² + f'(τ) τ''``."""
    span = t[-1] - t[0]
    start = t[0] + 0.5 * (1.0 - share) * span - ramp
    stop = start + share * span + 2 * ramp
    tau, rate, change = t.copy(), np.ones_like(t), np.zeros_like(t)
    down = (t >= start) & (t < start + ramp)
    s = (t[down] - start) / ramp
    tau[down] = start + ramp * (s - (2.5 * s**4 - 3 * s**5 + s**6))
    rate[down] = 1.0 - minimum_jerk(s)[0]
    change[down] = -minimum_jerk(s)[1] / ramp
    still = (t >= start + ramp) & (t < stop - ramp)
    tau[still], rate[still] = start + 0.5 * ramp, 0.0
    up = (t >= stop - ramp) & (t < stop)
    s = (t[up] - stop + ramp) / ramp
    tau[up] = start + 0.5 * ramp + ramp * (2.5 * s**4 - 3 * s**5 + s**6)
    rate[up] = minimum_jerk(s)[0]
    change[up] = minimum_jerk(s)[1] / ramp
    after = t >= stop
    tau[after] = t[after] - (stop - start - ramp)
    q, dq, ddq = motion.evaluate(tau)
    return q, dq * rate[:, None], ddq * rate[:, None] ** 2 + dq * change[:, None]


#: when each role's record starts after the sensor is switched on (s): training while it warms, the others later
WARMED = {"train": 0.0, "validate": 40.0, "test": 80.0}


def warming(t: np.ndarray, role: str, n: int, minutes: float = 0.5) -> np.ndarray:
    """A torque sensor's bias as it warms up: ``1 − exp(−(t + t₀)/T)`` (``t₀`` the record's start after switching
    on, :data:`WARMED`; ``T`` = ``minutes``), a column per joint, the sign alternating along the joints."""
    level = 1.0 - np.exp(-(t - t[0] + WARMED[role]) / (60.0 * minutes))
    return np.outer(level, (-1.0) ** np.arange(n))


def extra_torque(case: Lab, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """The truth's torque beyond the plain class, joint side."""
    if callable(case.extra):
        return case.extra(q, dq)
    n = q.shape[1]
    out = np.zeros_like(q)
    if case.extra == "position coulomb":  # an eccentric gear: Coulomb friction ±50 % of its level over a turn
        phase = np.linspace(0.0, PI, n)
        out = np.linspace(1.0, 3.0, n) * 0.5 * np.sin(q + phase) * np.sign(dq)
    if case.extra == "spring":  # springs pulling back to their rest positions (the motor holds k (q - q0)): a
        out[:, 0] = 20.0 * (q[:, 0] - 0.3)  # cable harness twisted about the vertical base axis (no gravity term
        out[:, 1] = 30.0 * (q[:, 1] + 0.5)  # absorbs it), 20 N m/rad about 0.3 rad; a gas spring on the shoulder
    return out


def confined(limits, joint: int, share: float) -> SimpleNamespace:
    """``limits`` with joint ``joint``'s range cut to its lower ``share`` (its speed limit scaled alike)."""
    lower, upper, velocity = limits.lower.copy(), limits.upper.copy(), limits.velocity_limit.copy()
    upper[joint] = lower[joint] + share * (upper[joint] - lower[joint])
    velocity[joint] *= share
    return SimpleNamespace(n_joints=limits.n_joints, lower=lower, upper=upper, velocity_limit=velocity)


def true_theta(case: Lab, folder: Path) -> np.ndarray:
    """The truth's parameters in the frames of the regressor's links (the URDF's, which differ from the DH table's):
    the true robot written as a URDF (``folder/true_bodies.urdf``) and read back, its bodies ±20 % and friction as
    :func:`tests.test_unseen_robots.truth` draws them, each joint's friction and offset scaled by the case's
    ``friction_scale``. (Until h-extrap the DH table's parameters ±20 % were read in the URDF's frames: bodies far
    from the description, some not rigid bodies.)"""
    true_urdf = folder / "true_bodies.urdf"
    true_urdf.write_text(robot_urdf(case.robot()))
    model = build_model(load_robot(urdf=true_urdf), "internal", FRICTION)
    theta = truth(model)
    for index, name in enumerate(model.parameter_names):
        if case.friction_scale and name.startswith(("fv", "fc", "off")):
            theta[index] *= case.friction_scale[int("".join(filter(str.isdigit, name))) - 1]
    return theta


def write_records(case: Lab, folder: Path) -> tuple[Path, dict, dict, np.ndarray]:
    """The description and the records of each role as the lab's logger writes them: ``(urdf, records, files,
    spread)``; the plain fit's records are what a user reading the file keeps (blank rows and repeated stamps left
    out)."""
    from benchmarks.bench_real_robots import Record

    robot = case.robot()
    described = cad_without_motors(robot) if case.wrong_bodies else robot
    urdf = folder / "robot.urdf"
    urdf.write_text(robot_urdf(described))
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)  # the regressor: the same kinematics
    theta = true_theta(case, folder)
    limits = SimpleNamespace(n_joints=robot.n_joints, lower=np.asarray(robot.lower, float),
                             upper=np.asarray(robot.upper, float), velocity_limit=np.asarray(robot.velocity_limit, float))
    gains = np.asarray(case.gains) if case.gains else np.ones(robot.n_joints)
    spread, records, files = None, {}, {}
    for role, log, seed in (("train", case.train, 11), ("validate", case.validate, 12), ("test", case.test, 13)):
        generator = np.random.default_rng(1000 + seed)
        t = times(log, generator)
        motion = {"test": case.test_motion, "validate": case.validate_motion}.get(role, "fourier")
        within = confined(limits, *case.trained_range) if case.trained_range and role != "test" else limits
        if callable(motion):
            q, dq, ddq = motion(limits, seed, t)
        elif motion == "point-to-point":
            q, dq, ddq = point_to_point(limits, seed, t, rest=case.rest)
        elif motion == "jog":
            q, dq, ddq = jog(limits, seed, t)
        elif case.halted and role in case.halted_in:
            q, dq, ddq = halt(random_fourier(within, seed=seed, frequency_hz=log.motion_hz), t, case.halted)
        else:
            q, dq, ddq = random_fourier(within, seed=seed, frequency_hz=log.motion_hz).evaluate(t)
        tau = model.predict(theta, q, dq, ddq) + extra_torque(case, q, dq)
        if case.armature:  # the rotors' inertia, reflected through the gears
            tau = tau + np.asarray(case.armature) * ddq
        tau = tau / gains
        if spread is None:
            spread = tau.std(axis=0)
            if case.equal_noise:  # a sensor's noise in N m, whatever the joint's load
                spread = np.full_like(spread, spread.mean())
        if case.sensed is not None:
            tau = case.sensed(tau, spread)
        tau = tau + generator.normal(0.0, 1.0, tau.shape) * NOISE * spread
        if case.drift:
            tau = tau + case.drift * spread * warming(t, role, tau.shape[1])
        t, q, dq, tau, frame = logged(t, q, dq, tau, log, generator)
        table = pd.DataFrame(frame)
        keep = np.ones(t.shape[0], dtype=bool)
        if case.dropouts:  # a row's values lost, its time stamp written
            blank = generator.choice(np.arange(5, t.shape[0] - 5), case.dropouts, replace=False)
            table.loc[blank, [name for name in table.columns if name != "t"]] = np.nan
            keep[blank] = False
        if case.duplicates:  # a row written twice
            twice = np.sort(generator.choice(np.arange(5, t.shape[0] - 5), case.duplicates, replace=False))
            table = pd.concat([table, table.iloc[twice]]).sort_index(kind="stable").reset_index(drop=True)
        files[role] = folder / f"{role}.csv"
        table.to_csv(files[role], index=False, float_format="%.10g")
        records[role] = Record(t[keep], q[keep], tau[keep], dq[keep] if log.velocity else None)
    return urdf, records, files, spread


def run_lab(case: Lab, folder: Path, *, rewritten: Callable[[Path], None] | None = None,
            reading: tuple[str, ...] = (), options: tuple[str, ...] = (),
            seconds: Callable[[np.ndarray], np.ndarray] | None = None) -> dict:
    """Write the records, run the verbs and the plain fit: per joint test MSE of each on the same samples; check
    that ``oed predict`` reproduces each verb's reported validation error. ``rewritten``: what a logger does to
    each file after the plain fit's records are kept (e.g. angles written in degrees), ``reading`` the options
    every verb is given to read the files so written, ``options`` those of the fitting verbs only (a
    ``--transmission``: the result holds it for ``oed predict``), ``seconds`` what maps the predictions' time stamps
    to the simulation's (a logger's clock that does not start at zero)."""
    from benchmarks.bench_real_robots import PlainFit

    urdf, records, files, spread = write_records(case, folder)
    for path in files.values() if rewritten is not None else ():
        rewritten(path)
    plain = PlainFit(["--urdf", str(urdf)])
    rate = min(log.rate_hz for log in (case.train, case.validate, case.test))  # a cut-off every record can take
    cutoff, plain_theta = plain.fit(records["train"], records["validate"], rate_hz=rate)
    predicted_plain, kept = plain.predict(records["test"], cutoff, plain_theta)
    outcome = verbs_against_the_plain_fit(urdf, files, records["test"], kept, predicted_plain, folder,
                                          reading=reading, options=options, seconds=seconds)
    return {**outcome, "cutoff": cutoff, "floor": (NOISE * spread) ** 2}


def verbs_against_the_plain_fit(urdf: Path, files: dict, test, kept: np.ndarray, predicted_plain: np.ndarray,
                                folder: Path, *, options: tuple[str, ...] = (), reading: tuple[str, ...] = (),
                                seconds: Callable[[np.ndarray], np.ndarray] | None = None) -> dict:
    """The default ``oed identify`` (told the plain fit's model class) and ``oed diagnose`` on ``files``'
    training and validation records (``options`` declared to both, ``reading`` to every verb: how the log reads),
    then ``oed predict`` on the validation record (its error against the one each verb reported) and on the test
    record (:func:`tests.test_unseen_robot_realities.scored_on_test`, its time stamps mapped by ``seconds``):
    ``mse`` (each verb's and the plain fit's on its samples), ``exits`` (a command's message where one exited),
    ``effects``, ``selections`` and ``reproduced`` (relative) per verb."""
    mse, exits, effects, selections, reproduced = {}, {}, {}, {}, {}
    for label, verb, more in (("default", "identify", ["--friction", FRICTION]), ("diagnose", "diagnose", [])):
        result = folder / f"{label}.json"
        code, message = quiet([verb, "--urdf", str(urdf), "--data", str(files["train"]), "--validate",
                               str(files["validate"]), *options, *reading, *more, "--out", str(result)])
        if code != 0:
            exits[label] = message
            continue
        summary = json.loads(result.read_text())
        effects[label], selections[label] = named_and_chosen(summary)
        metrics = folder / f"{label}_validate.json"
        code, message = quiet(["predict", "--model", str(result), "--data", str(files["validate"]), *reading,
                               "--metrics", str(metrics), "--out", str(folder / f"{label}_validate.csv")])
        if code != 0:
            exits[label] = message
            continue
        _, reported, _ = reported_models(summary)
        reproduced[label] = relative(json.loads(metrics.read_text())["mse"], reported)
        scored = scored_on_test(result, files["test"], folder / f"{label}_test.csv", test, kept, predicted_plain,
                                reading=reading, seconds=seconds)
        if isinstance(scored, str):
            exits[label] = scored
            continue
        mse[label], mse[f"plain OLS ({label}'s samples)"] = scored
    return {"mse": mse, "exits": exits, "effects": effects, "selections": selections, "reproduced": reproduced}


LABS = (
    Lab("PUMA 3 joints, a log with 12 blank rows and 15 rows written twice, 8 s / 3 s / 5 s at 250 Hz, no dq",
        puma(3), Log(8.0, 250.0, velocity=False), Log(3.0, 250.0, velocity=False), Log(5.0, 250.0, velocity=False),
        dropouts=12, duplicates=15),
    Lab("PUMA 6 joints at 100 Hz, 12-bit encoders, no dq, 12 s / 4 s / 6 s", puma(6),
        *(Log(seconds, 100.0, velocity=False, quantum=2 * PI / 4096) for seconds in (12.0, 4.0, 6.0)), slow=True),
    # a strict xfail until the torques were fitted as recorded (h-flip): at 981c3cf, with the torques filtered at the
    # chosen 5 Hz (the Coulomb steps smeared), identify 0.474 total, joint 5 1.88x the plain fit; fitted as recorded,
    # 0.229 total, every joint below 0.45x (identify and diagnose)
    Lab("PUMA 6 joints, training 10 s at 1 kHz with dq, validation 3 s at 250 Hz, test 6 s at 100 Hz, no dq",
        puma(6), Log(10.0, 1000.0), Log(3.0, 250.0, velocity=False), Log(6.0, 100.0, velocity=False), slow=True),
    Lab("PUMA 6 joints, gear friction changing with position (Coulomb ±50 % over a turn), 10 s / 4 s / 6 s at "
        "250 Hz, no dq", puma(6), *(Log(seconds, 250.0, velocity=False) for seconds in (10.0, 4.0, 6.0)),
        extra="position coulomb", slow=True),
    Lab("PUMA 6 joints, springs not in the URDF (a cable harness on the base, a gas spring on the shoulder), "
        "10 s / 4 s / 6 s at 250 Hz",
        puma(6), *(Log(seconds, 250.0) for seconds in (10.0, 4.0, 6.0)), extra="spring", slow=True),
    Lab("UR10e-like, the URDF's inertials from CAD without motors (masses halved), 10 s / 4 s / 6 s at 500 Hz, "
        "logged dq", ur10e, *(Log(seconds, 500.0, motion_hz=0.1) for seconds in (10.0, 4.0, 6.0)),
        wrong_bodies=True, slow=True),
    Lab("UR10e-like, torques logged in motor units (per-joint unknown gains), point-to-point test, 500 Hz",
        ur10e, Log(10.0, 500.0, motion_hz=0.1), Log(4.0, 500.0, motion_hz=0.1), Log(8.0, 500.0),
        test_motion="point-to-point", gains=(0.08, 0.12, 0.05, 0.02, 0.025, 0.03), slow=True),
    Lab("UR10e-like, torques logged as currents (one unknown constant: 1/0.09 A per N m), Fourier test, 500 Hz",
        ur10e, Log(10.0, 500.0, motion_hz=0.1), Log(4.0, 500.0, motion_hz=0.1), Log(6.0, 500.0, motion_hz=0.1),
        gains=(0.09,) * 6, slow=True),
    Lab("PUMA 6 joints, periodic excitation (4 periods of 5 s, then 2 of another series), point-to-point test, "
        "250 Hz, no dq", puma(6), Log(20.0, 250.0, velocity=False), Log(10.0, 250.0, velocity=False),
        Log(10.0, 250.0, velocity=False), test_motion="point-to-point", slow=True),
    Lab("PUMA 6 joints, Fourier training and validation, a slow teach-pendant test (one joint jogged at a time at "
        "10 % speed), 250 Hz, logged dq", puma(6), Log(10.0, 250.0), Log(4.0, 250.0), Log(20.0, 250.0),
        test_motion="jog", slow=True),
)


@pytest.mark.parametrize("case", [pytest.param(case, id=case.name, marks=marks(case)) for case in LABS])
def test_the_defaults_run_and_predict_a_labs_log_as_well_as_a_plain_fit(case, tmp_path):
    outcome = run_lab(case, tmp_path)
    print(f"\nreproduced validation error (relative): {outcome['reproduced']}")
    as_well_as_the_plain_fit(case.name, outcome, f"chosen {outcome['selections']}; ")
    for label, error in outcome["reproduced"].items():
        assert error < RELATIVE, (label, error)


@pytest.mark.parametrize("robot", [puma(6), ur10e], ids=["PUMA 6 joints", "UR10e-like"])
def test_the_simulated_bodies_are_the_descriptions_within_20_percent(robot, tmp_path):
    """The truth the labs simulate, read by the regressor of the URDF the verbs are given: each link parameter the
    description's within ±20 % (its sign kept; zero where the description's is zero); the CAD-without-motors
    description's masses the true robot's halved."""
    case = Lab("truth", robot, Log(1.0, 250.0), Log(1.0, 250.0), Log(1.0, 250.0))
    theta = true_theta(case, tmp_path)
    described = load_robot(urdf=tmp_path / "true_bodies.urdf").standard_parameters
    links = theta[: described.shape[0]]
    zero = np.abs(described) < 1e-12
    assert np.all(links[zero] == 0.0)
    ratio = links[~zero] / described[~zero]
    assert np.all((ratio >= 0.8 - 1e-9) & (ratio <= 1.2 + 1e-9)), ratio.round(3)
    written = tmp_path / "cad.urdf"
    written.write_text(robot_urdf(cad_without_motors(robot())))
    masses = slice(0, described.shape[0], 10)
    assert np.allclose(load_robot(urdf=written).standard_parameters[masses], 0.5 * described[masses])


def test_dropouts_are_dropped_and_bridged_alike_in_memory_and_streamed(tmp_path):
    """A log whose rows lost their values (blank cells, the time stamp kept): the rows dropped with a warning, the
    record read as the rows kept (the torques as recorded), in memory and chunk by chunk alike; a row blank in part
    stays an error naming its cell; a run of blank rows longer than ``max_gap`` splits the record."""
    from estimation.data import BlankRowsWarning, NonFiniteError
    from estimation.data.records import read_measurements, read_record
    from estimation.streaming.chunks import read_chunks
    from tests.test_unseen_robots import urdf_of, write_record

    urdf = urdf_of("puma560:3", tmp_path)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    write_record(model, truth(model), Log(4.0, 250.0, velocity=False), 11, tmp_path / "clean.csv")
    table = pd.read_csv(tmp_path / "clean.csv")
    blank = [40, 41, 300, 777]
    table.loc[blank, [name for name in table.columns if name != "t"]] = np.nan
    table.to_csv(tmp_path / "dropouts.csv", index=False)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        memory = read_measurements(tmp_path / "dropouts.csv", model=model)
        chunks = list(read_chunks(tmp_path / "dropouts.csv", model, chunk_size=250))
    said = [str(item.message) for item in caught if issubclass(item.category, BlankRowsWarning)]
    assert len(said) == 2 and all("dropped 4 row(s)" in text and "first at row 40" in text for text in said), "\n".join(said)
    kept = np.setdiff1d(np.arange(len(table)), blank)
    recorded = memory.as_recorded
    assert np.array_equal(recorded.t, table["t"].to_numpy()[kept])
    assert np.array_equal(recorded.tau, table[["tau1", "tau2", "tau3"]].to_numpy()[kept])
    assert np.allclose(np.concatenate([chunk.t for chunk in chunks]), memory.t, rtol=0, atol=1e-12)
    assert np.allclose(np.vstack([chunk.tau for chunk in chunks]), memory.tau, rtol=0, atol=1e-12)
    table.loc[101, "tau2"] = np.nan  # a row blank in part: no dropout
    table.to_csv(tmp_path / "partial.csv", index=False)
    with pytest.raises(NonFiniteError, match="column tau2"), warnings.catch_warnings():
        warnings.simplefilter("ignore", BlankRowsWarning)
        read_measurements(tmp_path / "partial.csv", model=model)
    long = pd.read_csv(tmp_path / "clean.csv")
    long.loc[500:529, [name for name in long.columns if name != "t"]] = np.nan  # 0.12 s without values
    long.to_csv(tmp_path / "long.csv", index=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        segments = read_record(tmp_path / "long.csv", model=model)
    assert len(segments) == 2


def test_predict_filters_a_record_of_a_lower_rate_at_the_highest_cutoff_it_takes(tmp_path):
    """A model whose filter was chosen on records at 1 kHz (200 Hz) predicts a record logged at 100 Hz: the filter
    at 40 Hz there (0.4 of its rate), said in a warning, the error at the noise floor (it exited: "cutoff 200 Hz
    is not below the Nyquist frequency 50 Hz")."""
    import oed
    from tests.test_unseen_robots import urdf_of, write_record

    urdf = urdf_of("puma560:3", tmp_path)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    theta = truth(model)
    _, spread = write_record(model, theta, Log(6.0, 1000.0, velocity=False), 11, tmp_path / "train.csv")
    write_record(model, theta, Log(6.0, 100.0, velocity=False), 13, tmp_path / "test.csv", spread)
    run = oed.identify(urdf=urdf, data=tmp_path / "train.csv", friction=FRICTION, cutoff=200.0, method="ols")
    run.write(tmp_path / "result.json")
    predicted = oed.predict(model=tmp_path / "result.json", data=tmp_path / "test.csv")
    said = list(predicted.warnings)  # the warnings oed predict prints
    assert any("filtered at 40 Hz" in text and "200 Hz" in text for text in said), said
    mse = np.array(list(predicted.evaluation.prediction.mse.values()))
    assert np.all(mse < 1.5 * (NOISE * spread) ** 2), (mse / (NOISE * spread) ** 2).round(3)


@pytest.mark.parametrize(("validation_logged", "verbs"), [
    pytest.param(True, ("identify",), id="validation with dq, ddq"),
    pytest.param(False, ("identify",), id="validation without"),
    pytest.param(False, ("diagnose",), id="validation without, diagnose", marks=pytest.mark.slow)])
def test_records_without_the_logged_derivatives_the_training_record_has(validation_logged, verbs, tmp_path):
    """Training (and validation) logged by a controller with ``dq`` and ``ddq`` (the KUKA's kind of log), the test
    (and validation) record by another logger with positions and torques only. A validation record without: the
    verbs leave the training record's logged derivatives out, every record's motion derived alike (they exited:
    "validation data lacks the measured dq/ddq the training data hold"). A test record without: ``oed predict``
    derives its motion with the rule's filter and says so (it exited: "the data to predict lacks the measured
    dq/ddq the training data hold"). Either way the test record is predicted at the noise floor."""
    import oed
    from tests.test_unseen_robots import urdf_of

    urdf = urdf_of("puma560:3", tmp_path)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    theta = truth(model)
    spread = None
    for role, seed, seconds, logged_derivatives in (("train", 11, 10.0, True), ("validate", 12, 4.0, validation_logged),
                                                     ("test", 13, 5.0, False)):
        t = np.arange(0.0, seconds, 0.004)
        q, dq, ddq = random_fourier(model.robot, seed=seed, frequency_hz=0.2).evaluate(t)
        tau = model.predict(theta, q, dq, ddq)
        spread = tau.std(axis=0) if spread is None else spread
        tau = tau + np.random.default_rng(seed).normal(0.0, 1.0, tau.shape) * NOISE * spread
        frame = {"t": t, **{f"q{j + 1}": q[:, j] for j in range(3)}}
        if logged_derivatives:
            frame.update({f"dq{j + 1}": dq[:, j] for j in range(3)})
            frame.update({f"ddq{j + 1}": ddq[:, j] for j in range(3)})
        frame.update({f"tau{j + 1}": tau[:, j] for j in range(3)})
        pd.DataFrame(frame).to_csv(tmp_path / f"{role}.csv", index=False)
    records = {"data": tmp_path / "train.csv", "validate": tmp_path / "validate.csv"}
    for verb in verbs:
        run = oed.identify(urdf=urdf, **records, friction=FRICTION) if verb == "identify" else \
            oed.diagnose(urdf=urdf, **records)
        run.write(tmp_path / f"{verb}.json")
        predicted = oed.predict(model=tmp_path / f"{verb}.json", data=tmp_path / "test.csv")
        said = any("lacks the logged dq/ddq" in text and "Hz Butterworth filter" in text for text in predicted.warnings)
        assert said == validation_logged, predicted.warnings  # without: the model's own filter applies
        mse = np.array(list(predicted.evaluation.prediction.mse.values()))
        assert np.all(mse < 1.3 * (NOISE * spread) ** 2), (verb, (mse / (NOISE * spread) ** 2).round(3))


def test_a_fourier_model_predicts_another_motion_through_the_best_filter_it_scored(tmp_path):
    """Periodic excitation (the PUMA paper's): training and validation repeat at 0.2 Hz, so the derivatives are a
    Fourier fit at 0.2 Hz; the test record is point-to-point moves, which a series at 0.2 Hz does not describe (its
    derivatives were garbage: the PUMA 6 case above predicted 115x worse than the plain fit). ``oed predict``
    derives such a record by the best filter the choice scored, says so, and predicts it as well as the plain fit
    (per joint within 1.3x). The Fourier fit is asked for (``frequency=0.2``): with the torques fitted as recorded
    the default's choice on the validation record takes a Butterworth filter on this record (h-flip), where the
    filtered target had made the Fourier fit win."""
    import oed
    from benchmarks.bench_real_robots import PlainFit, at_recorded, resent
    from tests.test_unseen_robots import PER_JOINT, within

    case = Lab("small", puma(3), Log(20.0, 250.0, velocity=False), Log(10.0, 250.0, velocity=False),
               Log(8.0, 250.0, velocity=False), test_motion="point-to-point")
    urdf, records, files, spread = write_records(case, tmp_path)
    run = oed.identify(urdf=urdf, data=files["train"], validate=files["validate"], friction=FRICTION, frequency=0.2)
    run.write(tmp_path / "result.json")
    assert json.loads((tmp_path / "result.json").read_text())["preprocessing"]["method"] == "fourier"
    predicted = oed.predict(model=tmp_path / "result.json", data=files["test"])
    assert any("does not repeat at the model's fundamental 0.2 Hz" in text and "best filter the choice scored" in text
               for text in predicted.warnings), predicted.warnings
    predicted.write(out=tmp_path / "test_predicted.csv")
    plain = PlainFit(["--urdf", str(urdf)])
    cutoff, theta = plain.fit(records["train"], records["validate"])
    test = records["test"]
    reference, kept = plain.predict(test, cutoff, theta)
    table = pd.read_csv(tmp_path / "test_predicted.csv")
    rows, values = at_recorded(test.t, table["t"].to_numpy(), table[["tau1", "tau2", "tau3"]].to_numpy())
    use = kept[rows] & ~resent(test)[rows]
    rows, values = rows[use], values[use]
    mse = np.mean((test.tau[rows] - values) ** 2, axis=0)
    plain_mse = np.mean((test.tau[rows] - reference[rows]) ** 2, axis=0)
    assert np.all(within(mse, plain_mse, (NOISE * spread) ** 2, PER_JOINT)), (mse / plain_mse).round(3)
