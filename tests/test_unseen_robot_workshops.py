"""Robots and logs the project had not seen, twentieth round (issue 34), beside the other
``tests/test_unseen_robot*`` files (h-unseen20):

- a 5-joint education arm (waist, shoulder, elbow, wrist pitch and roll; 0.12 m links, 0.9 kg moving), its
  hobby gearboxes' light friction; and the same arm with a gear backlash of 1° on every joint, the encoders on
  the motors: the logged angle is the link's plus half the play on the side the gear's torque presses (a
  smooth turn over 5 % of the channel's spread), so each torque reversal moves the logged angle by the play
  while the link moves on;
- a 7-joint collaborative arm logged at 1 kHz whose joint-torque sensors' offsets drift slowly (linearly, 0.03 %
  of each channel's spread a second, its sign alternating along the joints): the training record at switch-on,
  the validation a minute later, the test two minutes later (an offset 3.6 % of the spread off the training's);
- a 6-joint arm on harmonic drives whose Coulomb friction rises with the gravity load the gear carries (4 % of
  the joint's gravity torque beside the truth's Coulomb level), a truth outside every candidate family;
- a short validation record (2 s) from a slow Fourier motion (0.1 Hz), and a test at another speed (a Fourier
  motion at 0.3 Hz); and the same with the 2 s validation at the test's speed.

No data are copied; each case simulates the robot as :mod:`tests.test_unseen_robot_days` does (the plain fit's
model class, :func:`tests.test_unseen_robots.truth`, each case's reality, white torque noise of 2 % of each
channel's spread), runs the default ``oed identify`` (told the plain fit's model class) and ``oed diagnose`` (its
own defaults), then ``oed predict`` on the test record no choice saw, against the plain Pinocchio least-squares
fit of ``benchmarks/bench_real_robots.py`` on the same recorded samples: per joint within 1.3x, in total at most
1.0x, each figure allowed its noise floor's sampling spread; ``oed predict`` on the validation record reproduces
the validation error each verb reported (relative 1e-6); no verb names an effect the truth does not hold."""

from __future__ import annotations

import functools

import numpy as np
import pandas as pd
import pytest

from dynamics.dh import DHLink, robot_from_dh
from dynamics.urdf_export import robot_urdf
from tests.test_unseen_robot_benches import marks
from tests.test_unseen_robot_days import Day, Logger, judged, logs
from tests.test_unseen_robot_kinds import cylinder
from tests.test_unseen_robot_labs import Lab, puma
from tests.test_unseen_robot_shops import seven_joints
from tests.test_unseen_robots import Log

PI = np.pi


def education_arm():
    """A 5-joint education arm (a hobby kit's: waist, shoulder, elbow, wrist pitch, wrist roll with a gripper):
    links of 0.12 m, 0.9 kg moving, servos of 1.5 to 6 N m at 3 to 5 rad/s, ±150° (the shoulder ±100°)."""
    rows = ((0.0, PI / 2, 0.08), (0.12, 0.0, 0.0), (0.12, 0.0, 0.0), (0.0, PI / 2, 0.0), (0.0, 0.0, 0.07))
    mass = (0.25, 0.22, 0.16, 0.12, 0.15)
    shape = ((0.06, 0.03, 1, (0.0, -0.02, 0.0)), (0.12, 0.02, 0, (-0.06, 0.0, 0.01)),
             (0.12, 0.018, 0, (-0.055, 0.0, 0.0)), (0.04, 0.02, 1, (0.0, 0.01, 0.0)),
             (0.07, 0.02, 2, (0.0, 0.0, -0.03)))
    lower = (-2.6, -1.75, -2.6, -2.6, -2.6)
    velocity = (3.0, 3.0, 4.0, 5.0, 5.0)
    effort = (6.0, 6.0, 4.0, 1.5, 1.5)
    links = [DHLink(*rows[j], inertial=cylinder(mass[j], *shape[j][:3], shape[j][3]), lower=lower[j],
                    upper=-lower[j], velocity=velocity[j], effort=effort[j]) for j in range(5)]
    return robot_from_dh("education_arm", links)


def backlash(degrees: float = 1.0, width: float = 0.05) -> Logger:
    """The motors' encoders of an arm whose gears have a play of ``degrees``: the logged angle of each joint is the
    link's plus half the play on the side the gear's torque presses, ``(b/2) tanh(τ_j / (width σ_j))`` (``σ_j`` the
    training record's torque spread: the gear turns over within ``width`` of it), so each torque reversal moves
    the logged angle by the play while the link does not (a dead zone of lost motion, as Nordin and Gutman's
    survey models it, *Automatica* 38, 2002, with the motor's pass through the gap taken as quick)."""
    spread: list[np.ndarray] = []

    def logger(role: str, table: pd.DataFrame, record) -> tuple[pd.DataFrame, object]:
        import dataclasses

        if not spread:  # the training record comes first
            spread.append(record.tau.std(axis=0))
        play = 0.5 * np.radians(degrees) * np.tanh(record.tau / (width * spread[0]))
        out = table.copy()
        for j in range(record.q.shape[1]):
            out[f"q{j + 1}"] = table[f"q{j + 1}"].to_numpy() + play[:, j]
        return out, dataclasses.replace(record, q=record.q + play)

    return logger


#: when each role's record starts after the torque sensors are switched on (s)
SESSION = {"train": 0.0, "validate": 60.0, "test": 120.0}


def drifting_offsets(share_per_second: float = 3e-4) -> Logger:
    """Joint-torque sensors whose offsets drift slowly and linearly: channel ``j`` reads ``τ_j + r_j (t + t₀)``,
    ``r_j`` ``share_per_second`` of the training record's spread a second with a sign alternating along the
    joints, ``t₀`` the record's start in the session (:data:`SESSION`): the validation record's offsets 1.8 % of
    the spread off the training's, the test's 3.6 %."""
    spread: list[np.ndarray] = []

    def logger(role: str, table: pd.DataFrame, record) -> tuple[pd.DataFrame, object]:
        import dataclasses

        if not spread:
            spread.append(record.tau.std(axis=0))
        n = record.tau.shape[1]
        rate = share_per_second * spread[0] * (-1.0) ** np.arange(n)
        drift = np.outer(record.t - record.t[0] + SESSION[role], rate)
        out = table.copy()
        for j in range(n):
            out[f"tau{j + 1}"] = table[f"tau{j + 1}"].to_numpy() + drift[:, j]
        return out, dataclasses.replace(record, tau=record.tau + drift)

    return logger


@functools.cache
def _gravity_model(text: str):
    import pinocchio as pin

    model = pin.buildModelFromXML(text)
    return model, model.createData()


def load_friction(robot, share: float = 0.04):
    """Harmonic drives' Coulomb friction rising with the load the gear carries: ``share |g_j(q)| sign(q̇_j)``
    beside the truth's Coulomb level, ``g(q)`` the gravity torque of the description's bodies (Pinocchio's
    ``computeGeneralizedGravity``), the load most of a slow arm's gears carry (Tuttle and Seering's harmonic
    drive measurements: friction growing with the transmitted torque)."""

    def law(q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        import pinocchio as pin

        model, data = _gravity_model(robot_urdf(robot()))
        gravity = np.array([pin.computeGeneralizedGravity(model, data, row).copy() for row in q])
        return share * np.abs(gravity) * np.sign(dq)

    return law


def ur_like():
    from tests.test_unseen_robot_kinds import ur10e

    return ur10e()


#: the short validation's miss, measured at 2d5c469 (h-unseen20; benchmarks/README.md's section says more)
SHORT_VALIDATION = (
    "identify 1.054 of the plain fit in total (joints 0.784 / 1.016 / 0.995 / 1.322 / 0.957 / 1.004), diagnose 1.035 "
    "(joint 4 1.263): the 2 s validation record of slow motion ties every cut-off from 4.25 to 100 Hz (scores 1.0057 "
    "to 1.0081 of the best, standard errors up to 0.005); the smallest score takes 7.5 Hz where the plain fit takes "
    "80 Hz and the training record's held-out blocks 100 Hz. On the test, three times faster, the 7.5 Hz filter's "
    "first and last 0.3 s carry four times the inner samples' error on tau4 (0.170 against 0.041 N m squared): on the "
    "inner samples the default is 1.025 of the same fit at 80 Hz, over all 1.097; identify --cutoff 80 gives 0.971 "
    "(joint 4 0.952), --method ols 1.058. Nothing false named; oed predict says the test leaves the training's "
    "speeds on joints 4 and 5 (3.2 rad/s against 1.96 and 1.63; joint 4's accelerations 5.7 times the training's "
    "RMS). The validation's speed, not its length, is the cause: 4 s of the same slow motion 1.072 (4.25 Hz taken, "
    "joint 1 2.15x), 2 s at the test's speed (0.3 Hz) 0.970 on both verbs (21.25 Hz)")

WORKSHOPS = (
    Day(Lab("a 5-joint education arm (0.12 m links, 0.9 kg moving, a hobby kit's light friction), 10 s / 4 s / 8 s "
            "at 250 Hz, no dq, point-to-point test", education_arm, *logs(), friction_scale=(0.02,) * 5,
            test_motion="point-to-point", slow=True)),
    Day(Lab("the 5-joint education arm with a gear backlash of 1 degree on every joint (the encoders on the "
            "motors), 10 s / 4 s / 8 s at 250 Hz, no dq, point-to-point test", education_arm, *logs(),
            friction_scale=(0.02,) * 5, test_motion="point-to-point", slow=True,
            xfail="the predictions hold, the effects do not: identify 0.925 of the plain fit in total (joints 0.440 / "
                  "1.236 / 0.818 / 1.087 / 1.070), diagnose 0.593 (0.458 / 0.910 / 0.356 / 0.677 / 0.646), but the "
                  "diagnosis names a delay of 6.0 ms on every channel and a sigmoid on tau5 (beside coulomb:tanh on "
                  "tau3 and tau4, counted as Coulomb): the lost motion has no family, and a delay is its reading as "
                  "a lag of the link behind the motor (half the play, 8.7 mrad, over the joints' mean speeds of 0.8 "
                  "to 1.65 rad/s: 5.3 to 10.9 ms); every channel is said 2.7x to 17x above its floor. Measured at 2d5c469 (h-unseen20)"),
        logger=backlash()),
    Day(Lab("a 7-joint collaborative arm at 1 kHz, joint-torque sensors whose offsets drift slowly (0.03 % of the "
            "spread a second; validation a minute, test two minutes after the training), 8 s / 3 s / 5 s, no dq, "
            "point-to-point test", seven_joints, *logs((8.0, 3.0, 5.0), rate=1000.0), test_motion="point-to-point",
            slow=True),
        logger=drifting_offsets()),
    Day(Lab("UR10e-like on harmonic drives, Coulomb friction rising with the gravity load (4 % of it), 10 s / 4 s / "
            "8 s at 500 Hz, logged dq, point-to-point test", ur_like,
            *logs(rate=500.0, velocity=True, motion_hz=0.1), extra=load_friction(ur_like),
            test_motion="point-to-point", slow=True,
            xfail="the predictions hold, one effect does not: identify 0.418 of the plain fit (joints 0.393 / 0.438 / "
                  "0.632 / 0.185 / 0.057 / 0.115), diagnose 0.432 (joint 2 0.455), but the diagnosis names "
                  "viscous:direction on tau2 (fvd2 0.434, p = 7e-18), a law the truth does not hold. Traced: the "
                  "truth's term beyond the plain class, 0.04 |g2(q)| sign(dq2), projects on |dq2| (beside dq2, "
                  "sign(dq2) and a constant) with a slope of 0.437 on the training path (the fitted 0.434), 0.136 on "
                  "the validation's and -0.147 on the test's: the training path moves the shoulder faster where it "
                  "carries more load, and the validation path a little too, so the law validates. Measured at "
                  "2d5c469 (h-unseen20)")),
    Day(Lab("PUMA 6 joints, a short validation record (2 s) of slow motion (0.1 Hz), the test a Fourier motion at "
            "0.3 Hz, 10 s / 2 s / 6 s at 250 Hz, no dq", puma(6), Log(10.0, 250.0, velocity=False, motion_hz=0.1),
            Log(2.0, 250.0, velocity=False, motion_hz=0.1), Log(6.0, 250.0, velocity=False, motion_hz=0.3),
            slow=True, xfail=SHORT_VALIDATION)),
    Day(Lab("PUMA 6 joints, a short validation record (2 s) at the test's speed (0.3 Hz), slow training (0.1 Hz), "
            "10 s / 2 s / 6 s at 250 Hz, no dq", puma(6), Log(10.0, 250.0, velocity=False, motion_hz=0.1),
            Log(2.0, 250.0, velocity=False, motion_hz=0.3), Log(6.0, 250.0, velocity=False, motion_hz=0.3),
            slow=True)),
)


@pytest.mark.parametrize("day", [pytest.param(day, id=day.name, marks=marks(day)) for day in WORKSHOPS])
def test_the_defaults_run_and_predict_a_workshops_robot_as_well_as_a_plain_fit(day, tmp_path):
    judged(day, tmp_path)


def test_the_education_arm_reads_as_pinocchio_reads_it_without_a_word(tmp_path):
    """The 5-joint education arm's description (0.39 m from the base to the tool, 0.9 kg moving) as a user's URDF:
    read without a warning (no unit check fires on a small arm in metres), its inverse dynamics Pinocchio's."""
    import warnings

    import pinocchio as pin

    from dynamics.pinocchio_bridge import to_pinocchio
    from dynamics.robots import load_robot

    path = tmp_path / "education_arm.urdf"
    path.write_text(robot_urdf(education_arm()))
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        robot = load_robot(urdf=path)
    assert robot.n_joints == 5 and not said, [str(item.message) for item in said]
    reference = pin.buildModelFromUrdf(str(path))
    ours = to_pinocchio(robot)
    generator = np.random.default_rng(3)
    for _ in range(5):
        q, dq, ddq = (generator.uniform(-1.0, 1.0, 5) for _ in range(3))
        np.testing.assert_allclose(pin.rnea(ours, ours.createData(), q, dq, ddq),
                                   pin.rnea(reference, reference.createData(), q, dq, ddq), rtol=1e-10, atol=1e-12)


def test_the_loggers_move_the_angles_by_the_play_and_the_torques_by_the_drift():
    """The two loggers of the slow cases do what they say: the backlash moves each logged angle by the whole play
    between a pressing torque and its reversal (half of it either way), the link's angle kept; the drifting
    offsets put each channel's offset ``r_j t₀`` off the training's at the record's start, alternating in sign."""
    from benchmarks.bench_real_robots import Record

    t = np.arange(0.0, 2.0, 0.004)
    tau = np.column_stack([np.sin(2 * PI * 0.5 * t), np.cos(2 * PI * 0.5 * t)])
    q = np.column_stack([0.1 * t, -0.2 * t])
    table = pd.DataFrame({"t": t, "q1": q[:, 0], "q2": q[:, 1], "tau1": tau[:, 0], "tau2": tau[:, 1]})
    record = Record(t, q, tau, None)
    played, moved = backlash(degrees=1.0)("train", table, record)
    offset = moved.q - q
    assert np.allclose(played[["q1", "q2"]].to_numpy(), moved.q)
    assert np.isclose(offset.max(), 0.5 * np.radians(1.0), rtol=1e-3)
    assert np.isclose(offset.min(), -0.5 * np.radians(1.0), rtol=1e-3)
    assert np.all(np.sign(offset[np.abs(tau) > 0.3]) == np.sign(tau[np.abs(tau) > 0.3]))
    drift = drifting_offsets(1e-3)
    spread = tau.std(axis=0)
    _, trained = drift("train", table, record)
    _, tested = drift("test", table, record)
    assert np.allclose(trained.tau[0], tau[0])
    assert np.allclose(tested.tau[0] - tau[0], 1e-3 * spread * np.array([1.0, -1.0]) * SESSION["test"])
