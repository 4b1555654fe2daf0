"""Robots and logs the project has not seen, as a new user's shop floor brings them (issue 34), beside the other
``tests/test_unseen_robot*`` files:

- a hand-written description whose revolute axes point the negative way (``0 0 -1``, ``0 -1 0``, ``-1 0 0``), the
  log's angles and torques in those joints' sense, the arm on a pedestal placed in the cell by a ``world`` link
  (a fixed joint with an offset and a yaw): the URDF's root is not the robot's base;
- a redundant 7-joint arm trained on Fourier motions, its test a self-motion only: the flange held still while the
  arm turns in its null space (the motion a user's collision detection sees when an operator pushes the elbow);
- the velocity column the controller's reference (``dq`` of the planned path), 8 ms ahead of the measured motion
  (the tracking lag), not the measured velocity;
- a time column of integer milliseconds (``time_ms``) at 400 Hz: the 2.5 ms period written as 2 and 3 ms steps;
- torques that carry the mains' hum aliased: the second harmonic of a 50.15 Hz supply (100.3 Hz) picked up by the
  sensors' cables and sampled at 100 Hz reads as a 0.3 Hz wave, a truth outside every candidate family (nothing
  beyond the plain class may be named);
- a controller's full log: beside the measured columns its desired positions, velocities and torques
  (``q_d1``, ``dq_d1``, ``tau_d1``), an estimated external torque (``tau_ext1``), motor currents, temperatures and a
  gripper's width, the columns in another order than the joints'.

No data are copied; every record is simulated as :mod:`tests.test_unseen_robot_labs` does (the plain fit's model
class, :func:`tests.test_unseen_robots.truth`, each case's effect, white torque noise of 2 % of each channel's
spread). Each case runs the default ``oed identify`` (told the plain fit's model class) and ``oed diagnose`` (its own
defaults), then ``oed predict`` on the test record no choice saw, against the plain Pinocchio least-squares fit of
``benchmarks/bench_real_robots.py`` on the same recorded samples (the plain fit reads the records as simulated,
before the logger's rewriting): per joint within 1.3x, in total at most 1.0x, each figure allowed its noise floor's
sampling spread; ``oed predict`` on the validation record reproduces the validation error each verb reported
(relative 1e-6); no verb names an effect the truth does not hold."""

from __future__ import annotations

import functools
import re
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from tests.test_unseen_robot_benches import Bench, judged, marks, written
from tests.test_unseen_robot_labs import Lab, puma
from tests.test_unseen_robot_rigs import seven_joint_urdf
from tests.test_unseen_robots import Log

FLIPPED = """<?xml version="1.0"?>
<robot name="flipped_arm">
  <link name="world"/>
  <joint name="cell_mount" type="fixed"><origin xyz="1.2 -0.4 0.75" rpy="0 0 0.7"/><parent link="world"/><child link="pedestal"/></joint>
  <link name="pedestal"><inertial><origin xyz="0 0 0.1"/><mass value="20"/><inertia ixx="0.5" ixy="0" ixz="0" iyy="0.5" iyz="0" izz="0.3"/></inertial></link>
  <joint name="j1" type="revolute"><origin xyz="0 0 0.3"/><axis xyz="0 0 -1"/><parent link="pedestal"/><child link="turret"/>
    <limit lower="-2.8" upper="2.8" velocity="2.0" effort="200"/></joint>
  <link name="turret"><inertial><origin xyz="0.02 0.01 0.08"/><mass value="9"/><inertia ixx="0.09" ixy="0.002" ixz="0.001" iyy="0.08" iyz="0" izz="0.06"/></inertial></link>
  <joint name="j2" type="revolute"><origin xyz="0.1 0 0.2"/><axis xyz="0 -1 0"/><parent link="turret"/><child link="upper"/>
    <limit lower="-1.6" upper="1.6" velocity="2.0" effort="200"/></joint>
  <link name="upper"><inertial><origin xyz="0.2 0.01 0.02"/><mass value="7"/><inertia ixx="0.02" ixy="0" ixz="0.003" iyy="0.12" iyz="0" izz="0.11"/></inertial></link>
  <joint name="j3" type="revolute"><origin xyz="0.45 0 0"/><axis xyz="0 1 0"/><parent link="upper"/><child link="fore"/>
    <limit lower="-2.2" upper="2.2" velocity="2.5" effort="120"/></joint>
  <link name="fore"><inertial><origin xyz="0.16 0 -0.01"/><mass value="4"/><inertia ixx="0.008" ixy="0" ixz="0" iyy="0.045" iyz="0.001" izz="0.044"/></inertial></link>
  <joint name="j4" type="revolute"><origin xyz="0.35 0 0" rpy="0 0.3 0"/><axis xyz="-1 0 0"/><parent link="fore"/><child link="wrist"/>
    <limit lower="-2.6" upper="2.6" velocity="3.5" effort="40"/></joint>
  <link name="wrist"><inertial><origin xyz="0.04 0.015 0.02"/><mass value="1.5"/><inertia ixx="0.003" ixy="0.0002" ixz="0" iyy="0.004" iyz="0" izz="0.0035"/></inertial></link>
</robot>
"""


def flipped():
    return load_robot(urdf=written(FLIPPED))


def as_written_by_hand(path: Path) -> None:
    """The description the verbs and the plain fit read: :data:`FLIPPED` as written (the simulation's regressor
    reads the toolkit's export of it; :func:`test_negative_axes_and_a_placed_base_predict_as_pinocchio_does`
    holds the two alike)."""
    (path.parent / "robot.urdf").write_text(FLIPPED, encoding="utf-8")


@functools.cache
def seven_joint_limited_urdf() -> str:
    """:func:`tests.test_unseen_robot_rigs.seven_joint_urdf` with its continuous joints limited to ±170° (as the
    KUKA iiwa's): revolute joints only."""
    text = re.sub(r'type="continuous">((?:(?!</joint>).)*?)<limit ', r'type="revolute">\1<limit lower="-2.967" '
                  r'upper="2.967" ', seven_joint_urdf(), flags=re.DOTALL)
    assert "continuous" not in text
    return text


def seven_joints():
    return load_robot(urdf=written(seven_joint_limited_urdf()))


@functools.cache
def _kinematics():
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(written(seven_joint_limited_urdf())))
    return model, model.createData()


def self_motion(limits: SimpleNamespace, seed: int, t: np.ndarray) -> tuple[np.ndarray, ...]:
    """The 7-joint arm's flange held still (position and orientation) while the arm turns in the null space of its
    flange Jacobian ``J(q)`` (6 x 7): ``dq = s(t) n(q)``, ``n`` the unit null vector (its sign kept continuous),
    ``s(t)`` two sines (0.25 and 0.6 Hz) from a pose drawn within 30 % of each limited joint's half range;
    integrated to 1e-10 (DOP853), ``ddq`` the central difference of ``dq`` along the path (h = 0.1 ms)."""
    import pinocchio as pin
    from scipy.integrate import solve_ivp

    model, data = _kinematics()
    frame = model.nframes - 1
    generator = np.random.default_rng(seed)
    centre, half = 0.5 * (limits.lower + limits.upper), 0.5 * (limits.upper - limits.lower)
    start = centre + generator.uniform(-0.3, 0.3, limits.n_joints) * half
    start[3] = -1.2  # the elbow bent (away from the stretched arm's singularity)

    previous = [np.ones(limits.n_joints)]

    def direction(q: np.ndarray) -> np.ndarray:
        jacobian = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL)
        null = np.linalg.svd(jacobian)[2][-1]
        null = null if null @ previous[0] >= 0 else -null
        previous[0] = null
        return null

    def speed(time: np.ndarray | float) -> np.ndarray | float:
        return (0.5 * 2 * np.pi * 0.25 * np.cos(2 * np.pi * 0.25 * time)
                + 0.25 * 2 * np.pi * 0.6 * np.cos(2 * np.pi * 0.6 * time + 1.0))

    solution = solve_ivp(lambda time, q: speed(time) * direction(q), (t[0], t[-1] + 0.01), start, t_eval=t,
                         rtol=1e-10, atol=1e-12, dense_output=True, method="DOP853")
    q = solution.y.T
    dq = np.array([speed(time) * direction(state) for time, state in zip(t, q)])

    def velocity(time: float) -> np.ndarray:
        return speed(time) * direction(solution.sol(time))

    step = 1e-4
    ddq = np.array([(velocity(time + step) - velocity(time - step)) / (2 * step) for time in t])
    still = np.all(np.abs(dq) < 1e-9, axis=0)  # the elbow: an SRS arm's self-motion keeps its angle
    q[:, still], dq[:, still], ddq[:, still] = start[still], 0.0, 0.0  # at rest, not at rounding's speed (whose
    return q, dq, ddq  # sign would flip the truth's Coulomb friction from sample to sample)


def reference_velocity(lead_s: float = 0.008):
    """The velocity column the controller's reference: the logged ``dq`` at ``t`` the measured one at
    ``t + lead_s`` (the planned path ahead of the motion by the tracking lag), interpolated, held at the end."""

    def rewrite(path: Path) -> None:
        table = pd.read_csv(path)
        t = table["t"].to_numpy()
        for column in [name for name in table.columns if re.fullmatch(r"dq\d+", name)]:
            table[column] = np.interp(t + lead_s, t, table[column].to_numpy())
        table.to_csv(path, index=False, float_format="%.10g")

    return rewrite


def integer_milliseconds(path: Path) -> None:
    """The training and validation records' time column as a PLC writes it: ``time_ms``, whole milliseconds
    (rounded), no ``t``; the test record in seconds (the judge's samples at their instants)."""
    if path.stem == "test":
        return
    table = pd.read_csv(path)
    table.insert(0, "time_ms", np.round(table["t"].to_numpy() * 1e3).astype(np.int64))
    table.drop(columns="t").to_csv(path, index=False, float_format="%.10g")


def counted_milliseconds(path: Path, period_ms: float = 0.9993, phase_ms: float = 0.4) -> None:
    """The time column as a 1 kHz controller's logger writes it: ``time_ms``, a millisecond counter read at each
    sample (truncated), the samples ``period_ms`` apart on the counter's clock (the two clocks 0.07 % apart): now
    and then two rows hold the same stamp, the values of two samples; no ``t``. The training and validation
    records so; the test record in seconds (the judge's samples at their instants)."""
    if path.stem == "test":
        return
    table = pd.read_csv(path)
    counter = np.floor(np.arange(len(table)) * period_ms + phase_ms).astype(np.int64)
    table.insert(0, "time_ms", counter)
    table.drop(columns="t").to_csv(path, index=False, float_format="%.10g")


def aliased_hum(rate_hz: float, mains_hz: float = 50.15, share: float = 0.05):
    """The sensors' cables picking up the mains: its second harmonic (``2 mains_hz``) of ``share`` of each
    channel's spread (a phase per joint), sampled at ``rate_hz`` (it reads as ``|2 mains_hz − rate_hz|``)."""

    def sensed(tau: np.ndarray, spread: np.ndarray) -> np.ndarray:
        t = np.arange(tau.shape[0]) / rate_hz
        phase = np.linspace(0.0, 2.5, tau.shape[1])
        return tau + share * spread * np.sin(2 * np.pi * 2 * mains_hz * t[:, None] + phase)

    return sensed


def controller_log(path: Path) -> None:
    """The record as a controller's full log: beside ``t, q, dq, tau`` the desired ``q_d``, ``dq_d`` (the
    measured ones 5 ms later), ``tau_d`` (the torque without its noise, smoothed), ``tau_ext`` (small), motor
    currents ``i``, temperatures ``temp``, a gripper's ``gripper_width``; the columns in a shuffled order."""
    table = pd.read_csv(path)
    generator = np.random.default_rng(len(table))
    t = table["t"].to_numpy()
    joints = sorted(int(name[3:]) for name in table.columns if re.fullmatch(r"tau\d+", name))
    for j in joints:
        table[f"q_d{j}"] = np.interp(t + 0.005, t, table[f"q{j}"].to_numpy())
        if f"dq{j}" in table:
            table[f"dq_d{j}"] = np.interp(t + 0.005, t, table[f"dq{j}"].to_numpy())
        table[f"tau_d{j}"] = np.convolve(table[f"tau{j}"].to_numpy(), np.ones(9) / 9, mode="same")
        table[f"tau_ext{j}"] = generator.normal(0.0, 0.05, t.shape[0])
        table[f"i{j}"] = table[f"tau{j}"] / (0.1 * j) + generator.normal(0.0, 0.02, t.shape[0])
        table[f"temp{j}"] = 31.0 + 0.4 * j + generator.normal(0.0, 0.05, t.shape[0])
    table["gripper_width"] = 0.04 + 0.0 * t
    order = list(generator.permutation(table.columns))
    table[order].to_csv(path, index=False, float_format="%.10g")


def logs(seconds: tuple[float, float, float] = (10.0, 4.0, 6.0), rate: float = 250.0, velocity: bool = False,
         **more) -> tuple[Log, ...]:
    return tuple(Log(duration, rate, velocity=velocity, **more) for duration in seconds)


#: each case, the logger's rewrite of its files (or ``None``)
SHOPS = (
    (Bench(Lab("a 4-joint arm written by hand: revolute axes 0 0 -1, 0 -1 0, 0 1 0, -1 0 0, on a pedestal placed by "
               "a world link (offset and yaw), 10 s / 4 s / 6 s at 500 Hz, logged dq, point-to-point test", flipped,
               *logs(rate=500.0, velocity=True), test_motion="point-to-point", slow=True)),
     as_written_by_hand),
    (Bench(Lab("a 7-joint arm trained on Fourier motions, its test a self-motion only (the flange held still, the elbow at rest), "
               "10 s / 4 s / 6 s at 500 Hz, logged dq", seven_joints, *logs(rate=500.0, velocity=True),
               test_motion=self_motion, slow=True)),
     None),
    (Bench(Lab("PUMA 6 joints, the velocity column the controller's reference (8 ms ahead of the measured motion), "
               "10 s / 4 s / 6 s at 500 Hz", puma(6), *logs(rate=500.0, velocity=True), slow=True)),
     reference_velocity()),
    (Bench(Lab("PUMA 6 joints, time in integer milliseconds (time_ms) at 400 Hz: 2 and 3 ms steps, 10 s / 4 s / 6 s, "
               "no dq", puma(6), *logs(rate=400.0), slow=True)),
     integer_milliseconds),
    (Bench(Lab("PUMA 3 joints at 1 kHz, time a millisecond counter (time_ms, truncated) on a clock 0.07 % apart: "
               "stamps repeated now and then, 10 s / 4 s / 6 s, no dq", puma(3), *logs(rate=1000.0), slow=True)),
     counted_milliseconds),
    (Bench(Lab("PUMA 6 joints, the mains' hum aliased into the torques (100.3 Hz sampled at 100 Hz: a 0.3 Hz wave of "
               "5 % of each channel's spread), 12 s / 4 s / 6 s at 100 Hz, no dq", puma(6),
               *logs((12.0, 4.0, 6.0), rate=100.0), sensed=aliased_hum(100.0), slow=True)),
     None),
    (Bench(Lab("PUMA 6 joints, a controller's full log (desired q, dq, tau, external torque, currents, temperatures, "
               "a gripper's width; columns shuffled), 10 s / 4 s / 6 s at 500 Hz, logged dq", puma(6),
               *logs(rate=500.0, velocity=True), slow=True)),
     controller_log),
)


@pytest.mark.parametrize("bench, rewritten", [pytest.param(bench, rewritten, id=bench.name, marks=marks(bench))
                                              for bench, rewritten in SHOPS])
def test_the_defaults_run_and_predict_a_shops_log_as_well_as_a_plain_fit(bench, rewritten, tmp_path):
    judged(bench, tmp_path, rewritten)


def test_negative_axes_and_a_placed_base_predict_as_pinocchio_does():
    """:data:`FLIPPED` read by the toolkit (and its export read again) predicts the torques Pinocchio computes on
    the file as written: negative axes turn the joints' sense, the world link's offset and yaw leave gravity as it
    is."""
    import pinocchio as pin

    from dynamics.urdf_export import robot_urdf

    robot = flipped()
    generator = np.random.default_rng(0)
    q, dq, ddq = (generator.uniform(-1.0, 1.0, (6, 4)) for _ in range(3))
    reference = pin.buildModelFromUrdf(str(written(FLIPPED)))
    data = reference.createData()
    expected = np.array([pin.rnea(reference, data, *state) for state in zip(q, dq, ddq)])
    exported = load_robot(urdf=written(robot_urdf(robot)))
    for read in (robot, exported):
        model = build_model(read, "internal", "")
        assert np.allclose(model.predict(read.standard_parameters, q, dq, ddq), expected, atol=1e-9)


def test_a_millisecond_counter_at_1khz_keeps_every_row_alike_in_memory_and_streamed(tmp_path):
    """A 1 kHz log whose time is a millisecond counter (truncated) on a clock 0.07 % slower than the samples: now
    and then two rows share a stamp. Measured at 93a9290: those rows were dropped as a clock that did not tick (a
    sample lost, the next one a step early), the case above 1.103 in total against the plain fit (cut-off 10 Hz).
    Now the rows are placed on the regular clock through the stamps (each within its millisecond), every row kept,
    said in a :class:`QuantisedStampsWarning`, in memory and chunk by chunk alike. A clock that did not tick (the
    previous row's stamp, the next row two ticks on) and a lost row are not a quantised clock: as before."""
    from estimation.data import DuplicatedTimesWarning, QuantisedStampsWarning
    from estimation.data.records import read_record
    from estimation.streaming.chunks import read_chunks
    from tests.test_unseen_robots import FRICTION, truth, urdf_of, write_record

    urdf = urdf_of("puma560:3", tmp_path)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    write_record(model, truth(model), Log(3.0, 1000.0, velocity=False), 11, tmp_path / "clean.csv")
    table = pd.read_csv(tmp_path / "clean.csv")
    instants = np.arange(len(table)) * 0.9993e-3 + 0.4e-3  # the samples' instants on the counter's clock
    table["t"] = np.floor(instants * 1e3) / 1e3
    assert np.count_nonzero(np.diff(table["t"]) == 0) == 2
    table.to_csv(tmp_path / "counted.csv", index=False, float_format="%.10g")
    with pytest.warns(QuantisedStampsWarning, match="2 row\\(s\\) share their stamp") as caught:
        (memory,) = read_record(tmp_path / "counted.csv", model=model)
        chunks = list(read_chunks(tmp_path / "counted.csv", model, chunk_size=500))
    assert not [item for item in caught if issubclass(item.category, DuplicatedTimesWarning)]
    written = pd.read_csv(tmp_path / "counted.csv")
    assert memory.t.shape[0] == len(table) and np.array_equal(memory.tau, written[["tau1", "tau2", "tau3"]].to_numpy())
    assert np.ptp(memory.t - instants) < 2e-6  # the instants but for one offset (the band's centre): no step off
    assert np.array_equal(np.concatenate([chunk.t for chunk in chunks]), memory.t)
    assert np.array_equal(np.vstack([chunk.tau for chunk in chunks]), memory.tau)
    not_ticking = pd.read_csv(tmp_path / "clean.csv")
    not_ticking.loc[[400, 1500], "t"] = not_ticking["t"].to_numpy()[[399, 1499]]
    not_ticking.to_csv(tmp_path / "not_ticking.csv", index=False, float_format="%.10g")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        (dropped,) = read_record(tmp_path / "not_ticking.csv", model=model)
    said = [str(item.message) for item in caught if issubclass(item.category, DuplicatedTimesWarning)]
    assert len(said) == 1 and "dropped 2 row(s)" in said[0], said
    assert not [item for item in caught if issubclass(item.category, QuantisedStampsWarning)]
    assert dropped.as_recorded.t.shape[0] == len(not_ticking) - 2
