"""Robots and logs the project has not seen (issue 34): simulated records of robots with 1, 3, 4 (a prismatic torso
and an arm), 6 and 7 joints, with the hard cases of the issue's table (short records, a short validation record,
jittered and stalled time stamps, a logged velocity and none, 100 Hz to 1 kHz). For each, the default
``oed identify`` and ``oed diagnose`` (then ``oed predict`` on a test record of another motion) must run on their
defaults (no exit where an explicit option would have worked; ``identify`` told the plain fit's model class,
``diagnose`` only its own defaults: the viscous model, whose Coulomb friction and offsets it must find) and predict the test record about as well as a plain
Pinocchio least-squares fit of rigid body, viscous and Coulomb friction and offsets
(``benchmarks/bench_real_robots.py``: the plain fit, its cut-off chosen on the validation record, and the
comparison at the recorded samples every run predicted, a logger's re-sent rows left out): per joint within 1.3x, in total at most 1.0x, each
figure allowed its noise floor's sampling spread (records at the floor can differ by chance only).

The truth is the plain fit's model class (rigid body, viscous, Coulomb, offset: :func:`truth`) with white torque
noise of 2 % of
each channel's spread; the records are the motion of :func:`oed.fourier.random_fourier` (a seed a record) at the
time stamps given, the torques at those states (a stalled logger re-sends the last sample it sent, the stalls taken
in time order)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import true_parameters
from dynamics.urdf_export import robot_urdf
from oed.fourier import random_fourier

HERE = Path(__file__).resolve().parent
FRICTION = "viscous,coulomb,offset"
NOISE = 0.02  # of each channel's standard deviation
PER_JOINT, TOTAL = 1.3, 1.0  # issue 34's margins against the plain fit


@dataclass(frozen=True)
class Log:
    """How one record is logged: its duration, rate, whether the velocity is logged, the time stamps' defects."""

    seconds: float
    rate_hz: float
    velocity: bool = True
    jitter: float = 0.0  # of a step, uniform
    stalls: int = 0  # runs of re-sent samples
    bursts: int = 0  # stamps on receipt: a logger that stalls 5 steps, then delivers the samples in a burst
    quantum: float = 0.0  # the encoders' resolution (rad or m): positions rounded to it
    velocity_noise: float = 0.0  # white noise on a logged velocity, of its channel's spread
    motion_hz: float = 0.2  # the motion's fundamental (five harmonics)


@dataclass(frozen=True)
class UnseenCase:
    name: str
    robot: str  # a URDF path, or "puma560:3"
    train: Log
    validate: Log
    test: Log
    slow: bool = False
    xfail: str = ""  # the figures measured on the code of the day, where a case misses its target


def marks(case: UnseenCase) -> list[pytest.MarkDecorator]:
    chosen = [pytest.mark.slow] if case.slow else []
    if case.xfail:
        chosen.append(pytest.mark.xfail(strict=True, reason=case.xfail))
    return chosen


def truth(model) -> np.ndarray:
    """The true parameters: the description's bodies perturbed by ±20 %, viscous friction in 2–10, Coulomb friction
    from 1 to 3 and offsets of ±0.5 to ±1 along the joints (:func:`dynamics.simulation.synthetic.true_parameters`)."""
    n = model.robot.n_joints
    return true_parameters(model, seed=0, coulomb=np.linspace(1.0, 3.0, n),
                           offset=np.linspace(0.5, 1.0, n) * (-1.0) ** np.arange(n))


def urdf_of(robot: str, folder: Path) -> Path:
    """The robot's URDF: a path, ``shared:PATH`` under ``../shared/data`` (skipped when absent), or ``NAME:JOINTS``
    of a built-in robot written as a URDF."""
    if robot.startswith("shared:"):
        from tests.conftest import shared_data

        return shared_data(*robot.removeprefix("shared:").split("/"))
    if robot.endswith(".urdf"):
        return Path(robot)
    name, joints = robot.split(":")
    path = folder / f"{name}{joints}.urdf"
    path.write_text(robot_urdf(load_robot(name, joints=int(joints))))
    return path


def times(log: Log, generator: np.random.Generator) -> np.ndarray:
    step = 1.0 / log.rate_hz
    t = np.arange(0.0, log.seconds, step)
    if log.jitter:
        t = t + generator.uniform(-log.jitter, log.jitter, t.shape[0]) * step
        t = np.maximum.accumulate(t + np.arange(t.shape[0]) * 1e-9)  # still increasing
    return t


def received(t: np.ndarray, log: Log, generator: np.random.Generator) -> np.ndarray:
    """The time stamps as logged: with ``bursts``, five samples at a time stamped when they arrive together
    (10 µs apart, just before the next sample), the motion and torques still those of their sampling times."""
    t = t.copy()
    for start in generator.choice(np.arange(20, t.shape[0] - 20, 10), log.bursts, replace=False):
        t[start:start + 5] = t[start + 5] - 1e-5 * np.arange(5, 0, -1)
    return t


def write_record(model, theta, log: Log, seed: int, path: Path, spread: np.ndarray | None = None):
    """One record at ``log``'s time stamps (another motion a seed); returns the plain fit's view of it."""
    from benchmarks.bench_real_robots import Record

    generator = np.random.default_rng(1000 + seed)
    t = times(log, generator)
    q, dq, ddq = random_fourier(model.robot, seed=seed, frequency_hz=log.motion_hz).evaluate(t)
    tau = model.predict(theta, q, dq, ddq)
    if spread is None:
        spread = tau.std(axis=0)
    tau = tau + generator.normal(0.0, 1.0, tau.shape) * NOISE * spread
    t, q, dq, tau, frame = logged(t, q, dq, tau, log, generator)
    pd.DataFrame(frame).to_csv(path, index=False)
    return Record(t, q, tau, dq if log.velocity else None), spread


def logged(t: np.ndarray, q: np.ndarray, dq: np.ndarray, tau: np.ndarray, log: Log, generator: np.random.Generator
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """The record as ``log``'s logger writes it: stalls, position quantum, velocity noise, bursts of time stamps;
    ``(t, q, dq, tau, columns)``, the columns ``t, q1.., [dq1..], tau1..``."""
    stalls = [(int(generator.integers(10, t.shape[0] - 20)), int(generator.integers(2, 6))) for _ in range(log.stalls)]
    for start, length in sorted(stalls):  # a stalled logger: the last sample it sent re-sent for a few time stamps
        for array in (q, dq, tau):  # (in time order: a stall that overlaps an earlier one re-sends what that sent)
            array[start:start + length] = array[start - 1]
    if log.quantum:
        q = np.round(q / log.quantum) * log.quantum
    if log.velocity_noise:
        dq = dq + generator.normal(0.0, 1.0, dq.shape) * log.velocity_noise * dq.std(axis=0)
    if log.bursts:
        t = received(t, log, generator)
    n = q.shape[1]
    frame = {"t": t, **{f"q{j + 1}": q[:, j] for j in range(n)}}
    if log.velocity:
        frame.update({f"dq{j + 1}": dq[:, j] for j in range(n)})
    frame.update({f"tau{j + 1}": tau[:, j] for j in range(n)})
    return t, q, dq, tau, frame


def run_case(case: UnseenCase, folder: Path) -> dict:
    from benchmarks.bench_real_robots import Case, compare

    urdf = urdf_of(case.robot, folder)
    robot = load_robot(urdf=urdf)
    model = build_model(robot, "internal", FRICTION)
    theta = truth(model)
    benchmark = Case(case.name, ["--urdf", str(urdf)], {}, {})  # identify: --friction FRICTION; diagnose: its defaults
    spread = None
    for role, log, seed in (("train", case.train, 11), ("validate", case.validate, 12), ("test", case.test, 13)):
        path = folder / f"{role}.csv"
        benchmark.records[role], spread = write_record(model, theta, log, seed, path, spread)
        benchmark.files[role] = path
    outcome = compare(benchmark, folder, labels=("default", "diagnose"))
    outcome["floor"] = (NOISE * spread) ** 2
    return outcome


#: the slow torso + arm (no xfail since h-swap): diagnose was 0.82/0.39/1.01/1.98x the plain fit, coulomb:tanh on tau4 where the truth is the sign law, the plain-law swap refused on the unconstrained fits (tau3 0.049 -> 0.073 as shared rigid-body parameters moved); judged on the default answer's candidates (as fitted or consistent refit) it is adopted: 0.82/0.39/0.94/0.80x

SHORT_VALIDATION = Log(2.0, 250.0)  # the TIAGo's: a validation record too short for the toolkit's own cut-off
CASES = (
    UnseenCase("puma 3 joints, 12 s train, 2 s validation, logged dq", "puma560:3", Log(12.0, 250.0),
               SHORT_VALIDATION, Log(6.0, 250.0)),
    UnseenCase("EMPS-like axis (1 prismatic joint), 3.7 s records at 1 kHz, no dq",
               str(HERE.parent / "dynamics" / "robots" / "emps.urdf"), Log(3.7, 1000.0, velocity=False),
               Log(3.7, 1000.0, velocity=False), Log(3.7, 1000.0, velocity=False)),
    UnseenCase("torso + 3-joint arm, 100 Hz, jittered and stalled, no dq", str(HERE / "data" / "torso_arm.urdf"),
               Log(10.0, 100.0, velocity=False, jitter=0.3, stalls=5), Log(4.0, 100.0, velocity=False, jitter=0.3,
                                                                               stalls=2),
               Log(6.0, 100.0, velocity=False, jitter=0.3, stalls=3)),
    UnseenCase("arm6, 3.5 s records at 500 Hz, logged dq, jittered", str(HERE.parent / "dynamics" / "robots" /
                                                                       "arm6_collision.urdf"),
               Log(3.5, 500.0, jitter=0.2), Log(3.5, 500.0, jitter=0.2), Log(3.5, 500.0, jitter=0.2), slow=True),
    UnseenCase("puma 6 joints, 12 s train, 2 s validation at 1 kHz, no dq, stalled", "puma560:6",
               Log(12.0, 1000.0, velocity=False, stalls=10), Log(2.0, 1000.0, velocity=False, stalls=2),
               Log(5.0, 1000.0, velocity=False), slow=True),
    UnseenCase("puma 6 joints, 500 Hz, 10 s / 3 s / 4 s, logged dq, stamped on receipt (bursts)", "puma560:6",
               Log(10.0, 500.0, bursts=8), Log(3.0, 500.0, bursts=3), Log(4.0, 500.0, bursts=3), slow=True),
    UnseenCase("puma 6 joints, 3 s records at 100 Hz, no dq", "puma560:6", Log(3.0, 100.0, velocity=False),
               Log(3.0, 100.0, velocity=False), Log(3.0, 100.0, velocity=False), slow=True),
    UnseenCase("servo arm (4 joints), 100 Hz, 8 s / 2 s, logged dq, jittered and stalled", "servo_arm:4",
               Log(8.0, 100.0, jitter=0.4, stalls=3), Log(2.0, 100.0, jitter=0.4), Log(4.0, 100.0, jitter=0.4),
               slow=True),
    # the TIAGo's log: one long record, a 12 s validation window, slow motion and coarse encoders
    UnseenCase("torso + arm, a slow motion (0.05 Hz), 60 s / 12 s / 18 s, 1 mrad encoders, no dq",
               str(HERE / "data" / "torso_arm.urdf"), *(Log(seconds, 100.0, velocity=False, quantum=1e-3,
                                                            motion_hz=0.05) for seconds in (60.0, 12.0, 18.0)),
               slow=True),
    UnseenCase("torso + arm, 40 s / 1.5 s / 12 s, noisy logged dq, 1 mrad encoders, jittered and stalled",
               str(HERE / "data" / "torso_arm.urdf"),
               Log(40.0, 100.0, jitter=0.3, stalls=5, quantum=1e-3, velocity_noise=0.05),
               Log(1.5, 100.0, jitter=0.3, quantum=1e-3, velocity_noise=0.05),
               Log(12.0, 100.0, jitter=0.3, quantum=1e-3, velocity_noise=0.05), slow=True),
    UnseenCase("KUKA LWR4+ description (7 joints), 500 Hz, 12 s / 2 s / 6 s, 0.2 mrad encoders, no dq",
               "shared:kuka_lwr4/kuka_lwr4.urdf", Log(12.0, 500.0, velocity=False, quantum=2e-4),
               Log(2.0, 500.0, velocity=False, quantum=2e-4), Log(6.0, 500.0, velocity=False, quantum=2e-4),
               slow=True),
)


def within(values: np.ndarray, reference: np.ndarray, floor: np.ndarray, ratio: float) -> np.ndarray:
    """``values ≤ ratio · reference``, each allowed its floor's sampling spread (an MSE at the floor over ``N``
    samples scatters by ``floor · √(2/N)``; 5 % covers it on these records)."""
    return values <= ratio * reference + 0.05 * floor


@pytest.mark.parametrize("case", [pytest.param(case, id=case.name, marks=marks(case)) for case in CASES])
def test_the_defaults_run_and_predict_a_new_motion_as_well_as_a_plain_fit(case, tmp_path):
    outcome = run_case(case, tmp_path)
    mse, floor = outcome["mse"], outcome["floor"]
    plain = mse["plain OLS"]
    print(f"\n{case.name}: plain cut-off {outcome['cutoff']} Hz; diagnose adopted {outcome['effects']}; " + "; ".join(
        f"{label} {None if values is None else (values / plain).round(3).tolist()}" for label, values in mse.items()))
    for label in ("default", "diagnose"):
        assert mse[label] is not None, f"oed {label} failed on its defaults"
        assert np.all(within(mse[label], plain, floor, PER_JOINT)), (label, (mse[label] / plain).round(3))
        assert within(mse[label].sum(), plain.sum(), floor.sum(), TOTAL), (label, mse[label].sum() / plain.sum())


@pytest.mark.parametrize("explicit", [pytest.param({"cutoff": 1.5}, id="cutoff 1.5"),
                                      pytest.param({"method": "ols"}, id="ols", marks=pytest.mark.slow)])
def test_on_records_of_a_few_seconds_the_defaults_run_where_an_explicit_option_does(explicit, tmp_path):
    """The Schunk's 3.7 s records (issue 34: a 1.5 Hz cut-off refused there for the filter's settling at the edges):
    the library verbs run with the user's option and on their defaults, and the model predicts a new record."""
    import oed

    urdf = urdf_of("puma560:3", tmp_path)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    theta = truth(model)
    spread = None
    for role, seed in (("train", 11), ("validate", 12), ("test", 13)):
        _, spread = write_record(model, theta, Log(3.7, 250.0, velocity=False), seed, tmp_path / f"{role}.csv", spread)
    common = {"urdf": urdf, "data": tmp_path / "train.csv", "validate": tmp_path / "validate.csv", "friction": FRICTION}
    for settings in (explicit, {}):  # the user's option, then the defaults
        run = oed.identify(**common, **settings)
        run.write(tmp_path / "result.json")
        predicted = oed.predict(model=tmp_path / "result.json", data=tmp_path / "test.csv")
        assert all(np.isfinite(value) for value in predicted.evaluation.prediction.mse.values())
    oed.diagnose(**{key: value for key, value in common.items() if key != "friction"})
