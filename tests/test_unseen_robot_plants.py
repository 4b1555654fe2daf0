"""Robots and logs the project has not seen, as plants and labs bring them (issue 34), beside the other
``tests/test_unseen_robot*`` files (h-unseen16):

- a Stanford-like arm (waist, shoulder, a prismatic boom carrying a three-joint wrist: the boom's gravity load on the
  shoulder changes with its extension), a hand-written description;
- torques sampled and held at half the positions' rate (each torque value written on two rows: a drive's slower
  channel merged into the positions' table by repeating its last value, not by leaving blanks): a lag of half a
  row on average (2 ms at 250 Hz), which the diagnosis may name as a delay (it is the truth's);
- torques logged in kN·m (a heavy arm's controller unit), no units row, nothing declared;
- a description whose joint limits are narrower than the logged motion (the controller's soft limits, not the
  mechanical ones, written into the URDF: every range 60 % of the motion's about its centre, speeds halved);
- an arm on a mobile base whose platform accelerates (up to about 0.6 m/s², horizontal, a smooth random profile in
  each record) while the arm moves: the base's acceleration acts as gravity turned and scaled, a truth outside
  every candidate family (nothing beyond the plain class may be named);
- a joint driven through a cable whose moment arm changes with the angle (±15 % over its range), its torque sensed
  on the motor: a truth outside every candidate family;
- the time column written as ISO 8601 date-times (``2026-11-28 10:00:00.004``), as a database or pandas export
  writes it;
- the velocity column in degrees per second beside positions in radians (a drive's display unit);
- the time column a spreadsheet's date serial (days since 1899-12-30, a number): the verbs exit naming the
  column map that reads it, and with it predict as well as the plain fit.

No data are copied; every record is simulated as :mod:`tests.test_unseen_robot_labs` does (the plain fit's model
class, :func:`tests.test_unseen_robots.truth`, each case's reality, white torque noise of 2 % of each channel's
spread). Each case runs the default ``oed identify`` (told the plain fit's model class) and ``oed diagnose`` (its
own defaults), then ``oed predict`` on the test record no choice saw (a point-to-point motion: another kind than the
training's Fourier motion), against the plain Pinocchio least-squares fit of ``benchmarks/bench_real_robots.py`` on
the same recorded samples (it reads the records a user reads, and the description the simulation used): per joint
within 1.3x, in total at most 1.0x, each figure allowed its noise floor's sampling spread; ``oed predict`` on the
validation record reproduces the validation error each verb reported (relative 1e-6); no verb names an effect the
truth does not hold."""

from __future__ import annotations

import dataclasses
import re
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from tests.test_unseen_robot_benches import written
from tests.test_unseen_robot_days import Day, Logger, checked, logs
from tests.test_unseen_robot_kinds import ur10e
from tests.test_unseen_robot_labs import Lab, puma, true_theta
from tests.test_unseen_robots import FRICTION

#: a Stanford-like arm: a waist about the vertical, a shoulder about a horizontal axis, a boom sliding out along the
#: arm (0.05 to 0.45 m, its tail behind the shoulder), and a roll-pitch-roll wrist with a tool off its axis; masses
#: and lengths of a mid-size arm, split by hand
STANFORD = """<?xml version="1.0"?>
<robot name="stanford_like">
  <link name="base_link"><inertial><origin xyz="0 0 0.2"/><mass value="20"/><inertia ixx="0.4" ixy="0" ixz="0" iyy="0.4" iyz="0" izz="0.2"/></inertial></link>
  <joint name="waist" type="revolute"><origin xyz="0 0 0.4"/><axis xyz="0 0 1"/><parent link="base_link"/><child link="turret"/>
    <limit lower="-2.8" upper="2.8" velocity="1.5" effort="300"/></joint>
  <link name="turret"><inertial><origin xyz="0 0 0.08"/><mass value="8"/><inertia ixx="0.08" ixy="0" ixz="0" iyy="0.08" iyz="0" izz="0.05"/></inertial></link>
  <joint name="shoulder" type="revolute"><origin xyz="0 0 0.16"/><axis xyz="0 1 0"/><parent link="turret"/><child link="housing"/>
    <limit lower="-1.2" upper="1.2" velocity="1.2" effort="300"/></joint>
  <link name="housing"><inertial><origin xyz="0.03 0 0.02"/><mass value="6"/><inertia ixx="0.03" ixy="0" ixz="0" iyy="0.05" iyz="0" izz="0.05"/></inertial></link>
  <joint name="boom" type="prismatic"><origin xyz="0.1 0 0"/><axis xyz="1 0 0"/><parent link="housing"/><child link="boom_link"/>
    <limit lower="0.05" upper="0.45" velocity="0.4" effort="400"/></joint>
  <link name="boom_link"><inertial><origin xyz="0.05 0 0"/><mass value="3"/><inertia ixx="0.004" ixy="0" ixz="0" iyy="0.07" iyz="0" izz="0.07"/></inertial></link>
  <joint name="wrist_roll" type="revolute"><origin xyz="0.32 0 0"/><axis xyz="1 0 0"/><parent link="boom_link"/><child link="forearm"/>
    <limit lower="-2.8" upper="2.8" velocity="2.5" effort="40"/></joint>
  <link name="forearm"><inertial><origin xyz="0.04 0 0.01"/><mass value="1.2"/><inertia ixx="0.002" ixy="0" ixz="0" iyy="0.003" iyz="0" izz="0.003"/></inertial></link>
  <joint name="wrist_pitch" type="revolute"><origin xyz="0.09 0 0"/><axis xyz="0 1 0"/><parent link="forearm"/><child link="hand"/>
    <limit lower="-1.8" upper="1.8" velocity="2.5" effort="30"/></joint>
  <link name="hand"><inertial><origin xyz="0.05 0 0.01"/><mass value="0.8"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.0015" iyz="0" izz="0.0015"/></inertial></link>
  <joint name="flange_roll" type="revolute"><origin xyz="0.08 0 0"/><axis xyz="1 0 0"/><parent link="hand"/><child link="flange"/>
    <limit lower="-2.8" upper="2.8" velocity="3.0" effort="15"/></joint>
  <link name="flange"><inertial><origin xyz="0.03 0.02 0.01"/><mass value="0.6"/><inertia ixx="0.0008" ixy="0" ixz="0" iyy="0.0008" iyz="0" izz="0.0006"/></inertial></link>
</robot>
"""


def stanford():
    return load_robot(urdf=written(STANFORD))


def held(every: int = 2) -> Logger:
    """A drive's torque channel at ``1/every`` of the positions' rate, merged into their table by holding its last
    value: each torque written on ``every`` rows (the positions' own on each)."""

    def logger(role: str, table: pd.DataFrame, record) -> tuple[pd.DataFrame, object]:
        del role
        tau = record.tau.copy()
        rows = np.arange(tau.shape[0])
        tau = tau[rows - rows % every]
        out = table.copy()
        for joint in range(tau.shape[1]):
            out[f"tau{joint + 1}"] = tau[:, joint]
        return out, dataclasses.replace(record, tau=tau)

    return logger


def scaled_torques(factor: float) -> Logger:
    """The torque columns in another unit: each value times ``factor`` (1e-3: kN·m), nothing said."""

    def logger(role: str, table: pd.DataFrame, record) -> tuple[pd.DataFrame, object]:
        del role
        out = table.copy()
        for joint in range(record.tau.shape[1]):
            out[f"tau{joint + 1}"] = table[f"tau{joint + 1}"] * factor
        return out, dataclasses.replace(record, tau=record.tau * factor)

    return logger


def soft_limits(share: float = 0.6, speed: float = 0.5) -> Callable[[str], str]:
    """The description with each joint's range cut to ``share`` of its own about its centre and its speed limit
    times ``speed`` (the controller's soft limits written in place of the mechanical ones)."""

    def described(text: str) -> str:
        def cut(found: re.Match) -> str:
            lower, upper = float(found.group("lower")), float(found.group("upper"))
            centre, half = 0.5 * (lower + upper), 0.5 * share * (upper - lower)
            velocity = speed * float(found.group("velocity"))
            return (f'<limit{found.group("before")}lower="{centre - half!r}" upper="{centre + half!r}"'
                    f'{found.group("between")}velocity="{velocity!r}"')

        pattern = (r'<limit(?P<before>[^>]*?)lower="(?P<lower>[^"]+)"\s+upper="(?P<upper>[^"]+)"(?P<between>[^>]*?)'
                   r'velocity="(?P<velocity>[^"]+)"')
        changed, count = re.subn(pattern, cut, text)
        assert count, "no joint limit found"
        return changed

    return described


#: each role's base acceleration seed: a different profile in each record
PLATFORM_SEEDS = {"train": 21, "validate": 22, "test": 23}


def platform(lab: Lab, peak: float = 0.6) -> Logger:
    """An arm on a mobile base whose platform accelerates: a smooth random horizontal acceleration ``a(t)`` (three
    sines of 0.05 to 0.4 Hz along x and y, scaled to ``peak`` m/s²) acts on the arm as gravity ``-a`` beside the
    true one, so the torques gain ``G(q; -a)``: the truth's gravity torque (its bodies, frames and joints) with the
    gravity vector ``-a(t)``, linear in it."""
    truth_theta: dict[str, object] = {}

    def logger(role: str, table: pd.DataFrame, record) -> tuple[pd.DataFrame, object]:
        if not truth_theta:
            folder = Path(tempfile.mkdtemp(prefix="unseen-plants-"))
            theta = true_theta(lab, folder)
            model = build_model(load_robot(urdf=folder / "true_bodies.urdf"), "internal", FRICTION)
            rigid = np.array([0.0 if name.startswith(("fv", "fc", "off")) else value
                              for name, value in zip(model.parameter_names, theta)])
            truth_theta.update(robot=load_robot(urdf=folder / "true_bodies.urdf"), rigid=rigid)
        generator = np.random.default_rng(PLATFORM_SEEDS[role])
        t = record.t
        acceleration = np.zeros((t.shape[0], 2))
        for axis in range(2):
            for _ in range(3):
                frequency, phase = generator.uniform(0.05, 0.4), generator.uniform(0.0, 2 * np.pi)
                acceleration[:, axis] += generator.normal() * np.sin(2 * np.pi * frequency * t + phase)
        acceleration *= peak / np.max(np.linalg.norm(acceleration, axis=1))
        still = np.zeros_like(record.q)
        extra = np.zeros_like(record.tau)
        for axis in range(2):
            unit = np.zeros(3)
            unit[axis] = -1.0  # the platform accelerating along +axis: gravity along -axis, per m/s²
            turned = build_model(truth_theta["robot"].with_gravity(unit), "internal", FRICTION)
            extra += acceleration[:, [axis]] * turned.predict(truth_theta["rigid"], record.q, still, still)
        tau = record.tau + extra
        out = table.copy()
        for joint in range(tau.shape[1]):
            out[f"tau{joint + 1}"] = table[f"tau{joint + 1}"].to_numpy() + extra[:, joint]
        return out, dataclasses.replace(record, tau=tau)

    return logger


def cable(joint: int = 3, swing: float = 0.15) -> Logger:
    """Joint ``joint`` driven through a cable over a cam: the moment arm ``r(q) = r0 (1 + swing sin(q))``, the torque
    sensed on the motor side reading ``tau_j r0 / r(q)`` (the sensor's noise before it, as the truth's torque)."""

    def logger(role: str, table: pd.DataFrame, record) -> tuple[pd.DataFrame, object]:
        del role
        tau = record.tau.copy()
        tau[:, joint - 1] = tau[:, joint - 1] / (1.0 + swing * np.sin(record.q[:, joint - 1]))
        out = table.copy()
        out[f"tau{joint}"] = tau[:, joint - 1]
        return out, dataclasses.replace(record, tau=tau)

    return logger


def iso_times(start: str = "2026-11-28 10:00:00") -> Logger:
    """The time column as a database or pandas export writes it: ISO 8601 date-times (``2026-11-28
    10:00:00.004000``) from ``start`` (each record its own hour)."""

    def logger(role: str, table: pd.DataFrame, record) -> tuple[pd.DataFrame, object]:
        hour = {"train": 0, "validate": 1, "test": 2}[role]
        stamps = pd.Timestamp(start) + pd.Timedelta(hours=hour) + pd.to_timedelta(table["t"].to_numpy(), unit="s")
        return table.assign(t=stamps.strftime("%Y-%m-%d %H:%M:%S.%f")), record

    return logger


def velocity_in_degrees(role: str, table: pd.DataFrame, record) -> tuple[pd.DataFrame, object]:
    """The velocity columns in degrees per second, the positions in radians."""
    del role
    out = table.copy()
    for name in [column for column in table.columns if column.startswith("dq")]:
        out[name] = np.degrees(table[name])
    return out, record


@dataclass(frozen=True)
class Plant:
    """One case: a :class:`tests.test_unseen_robot_days.Day`, the torque unit the user's log is in (the noise
    floor scaled alike)."""

    day: Day
    unit: float = 1.0
    #: whether ``oed diagnose``'s test error must be at or below ``oed identify``'s (the held torques: h-logs3)
    diagnose_within_identify: bool = False

    @property
    def name(self) -> str:
        return self.day.name


def marks(plant: Plant) -> list[pytest.MarkDecorator]:
    chosen = [pytest.mark.slow] if plant.day.lab.slow else []
    if plant.day.lab.xfail:
        chosen.append(pytest.mark.xfail(strict=True, reason=plant.day.lab.xfail))
    return chosen


def judged(plant: Plant, folder: Path) -> None:
    from tests.test_unseen_robot_days import run_day

    outcome = run_day(plant.day, folder)
    checked(plant.name, {**outcome, "floor": outcome["floor"] * plant.unit**2}, plant.day.may_name)
    if plant.diagnose_within_identify:
        identify, diagnose = (float(np.sum(outcome["mse"][label])) for label in ("default", "diagnose"))
        assert diagnose <= identify, (diagnose, identify)


PLATFORM_LAB = Lab("PUMA 6 joints on a mobile base whose platform accelerates (up to 0.6 m/s^2, horizontal, not "
                   "modelled), 10 s / 4 s / 8 s at 250 Hz, no dq, point-to-point test", puma(6), *logs(),
                   test_motion="point-to-point", slow=True)

PLANTS = (
    Plant(Day(Lab("Stanford-like arm (waist, shoulder, a prismatic boom, a three-joint wrist), a hand-written URDF, "
                  "10 s / 4 s / 8 s at 250 Hz, no dq, point-to-point test", stanford, *logs(),
                  test_motion="point-to-point", slow=True),
              described=lambda text: STANFORD)),
    Plant(Day(Lab("PUMA 6 joints, torques sampled and held at half the positions' rate (each value on two rows), "
                  "10 s / 4 s / 8 s at 250 Hz, no dq, point-to-point test", puma(6), *logs(),
                  test_motion="point-to-point", slow=True),
              logger=held()),  # the repeats read as the channel's blanks (h-logs3): no lag left to name
          diagnose_within_identify=True),
    Plant(Day(Lab("UR10e-like, torques logged in kN m (no units row), 10 s / 4 s / 8 s at 500 Hz, logged dq, "
                  "point-to-point test", ur10e, *logs(rate=500.0, velocity=True, motion_hz=0.1),
                  test_motion="point-to-point", slow=True),
              logger=scaled_torques(1e-3)), unit=1e-3),
    Plant(Day(Lab("PUMA 6 joints, the URDF's limits narrower than the logged motion (soft limits: 60 % of each "
                  "range, speeds halved), 10 s / 4 s / 8 s at 250 Hz, no dq, point-to-point test", puma(6), *logs(),
                  test_motion="point-to-point", slow=True),
              described=soft_limits())),
    Plant(Day(PLATFORM_LAB, logger=platform(PLATFORM_LAB))),
    Plant(Day(Lab("PUMA 6 joints, joint 3 driven through a cable whose moment arm changes with the angle (+-15 %), "
                  "its torque sensed on the motor, 10 s / 4 s / 8 s at 250 Hz, no dq, point-to-point test", puma(6),
                  *logs(), test_motion="point-to-point", slow=True),
              logger=cable())),
    Plant(Day(Lab("PUMA 6 joints, the time column ISO 8601 date-times, 10 s / 4 s / 8 s at 250 Hz, no dq, "
                  "point-to-point test", puma(6), *logs(), test_motion="point-to-point", slow=True),
              logger=iso_times())),
    Plant(Day(Lab("PUMA 6 joints, the velocity logged in degrees per second beside radians, 10 s / 4 s / 8 s at "
                  "250 Hz, point-to-point test", puma(6), *logs(velocity=True), test_motion="point-to-point",
                  slow=True),
              logger=velocity_in_degrees)),
)


@pytest.mark.parametrize("plant", [pytest.param(plant, id=plant.name, marks=marks(plant)) for plant in PLANTS])
def test_the_defaults_run_and_predict_a_plants_log_as_well_as_a_plain_fit(plant, tmp_path):
    judged(plant, tmp_path)


def test_date_times_in_the_time_column_are_read_as_seconds_alike_in_memory_and_streamed(tmp_path):
    """The time column as ISO 8601 date-times (a ``t`` column with a blank row: a dropout; a ``timestamp`` column
    whose stamps carry a UTC offset that changes inside the record, as a summer-time change writes it), and as a
    Parquet timestamp type: read as the seconds since the first stamp, equal to the same log written in seconds, in
    memory and streamed, and said. At 6ee74d4 the CSV was refused as "row 0 holds text in every column … a second
    header line (units?)", the Parquet file as "column t holds datetime64[ns] dates or durations"."""
    import warnings

    from estimation.data.date_times import DateTimeStampsWarning
    from estimation.data.records import read_record
    from estimation.streaming.chunks import read_chunks

    t = np.arange(0.0, 2.0, 0.004)
    si = pd.DataFrame({"t": t, "q1": np.sin(t), "q2": np.cos(2 * t), "tau1": 3 * np.sin(3 * t), "tau2": np.cos(t) - 2})
    si.to_csv(tmp_path / "si.csv", index=False, float_format="%.17g")
    stamps = pd.Timestamp("2026-03-29 00:59:59") + pd.to_timedelta(t, unit="s")
    written = si.assign(t=stamps.strftime("%Y-%m-%d %H:%M:%S.%f"))
    written.loc[100, ["q1", "q2", "tau1", "tau2"]] = np.nan  # a dropout, its stamp kept
    written.to_csv(tmp_path / "iso.csv", index=False, float_format="%.17g")
    local = [(stamp + pd.Timedelta(hours=1)).strftime("%Y-%m-%dT%H:%M:%S.%f") + "+01:00" if stamp.hour == 0
             else (stamp + pd.Timedelta(hours=2)).strftime("%Y-%m-%dT%H:%M:%S.%f") + "+02:00" for stamp in stamps]
    si.drop(columns="t").assign(timestamp=local).to_csv(tmp_path / "offsets.csv", index=False, float_format="%.17g")
    si.assign(t=stamps).to_parquet(tmp_path / "stamps.parquet")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        (plain,) = read_record(tmp_path / "si.csv", require=("tau",))
    model = build_model(load_robot("puma560", joints=2), "internal")
    for name, dropped in (("iso.csv", 1), ("offsets.csv", 0), ("stamps.parquet", 0)):
        kept = np.setdiff1d(np.arange(t.shape[0]), [100] if dropped else [])
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            (converted,) = read_record(tmp_path / name, require=("tau",))
        said = [str(found.message) for found in caught if issubclass(found.category, DateTimeStampsWarning)]
        assert len(said) == 1 and "holds date-times" in said[0] and "since that stamp" in said[0], said
        for group in ("t", "q", "tau"):
            np.testing.assert_allclose(getattr(converted.as_recorded, group), getattr(plain, group)[kept],
                                       rtol=0, atol=1e-9, err_msg=f"{name} {group}")
        if name == "offsets.csv":  # the streamed path reads a column named t only
            continue
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            chunks = list(read_chunks(tmp_path / name, model, chunk_size=170))
        assert any(issubclass(found.category, DateTimeStampsWarning) for found in caught), name
        for group in ("t", "q", "tau"):
            streamed = np.concatenate([getattr(chunk, group) for chunk in chunks])  # a dropout bridged alike
            np.testing.assert_allclose(streamed, getattr(converted, group), rtol=0, atol=1e-9,
                                       err_msg=f"{name} streamed {group}")


#: a spreadsheet's date serial (days since 1899-12-30) of 2026-12-09 10:00, the records' start
SERIAL = 46000.0 + 10.0 / 24.0
DAYS_LAB = Lab("PUMA 3 joints, the time a spreadsheet's date serial (days), 8 s / 3 s / 5 s at 250 Hz, no dq, "
               "point-to-point test", puma(3), *logs((8.0, 3.0, 5.0)), test_motion="point-to-point")


def in_days(path: Path) -> None:
    """The record's time column rewritten as a spreadsheet's date-time serial: days since 1899-12-30 from
    :data:`SERIAL` (a number, as a spreadsheet saves a date-time cell to CSV)."""
    table = pd.read_csv(path)
    table["t"] = SERIAL + table["t"] / 86400.0
    table.to_csv(path, index=False, float_format="%.17g")


def test_a_time_column_in_days_exits_naming_the_option_that_reads_it(tmp_path):
    """The default ``oed identify`` on a log whose time is a spreadsheet's date serial (days: a step of 4.6e-8 at
    250 Hz) exits (code 2, no traceback) naming the ``--columns`` factor that reads it. At 6ee74d4 it read the
    days as seconds without a word (a 21.6 MHz record): exit 0, a model predicting the validation record 1.9x worse
    than the description's nominal one (PUMA 3, 8 s at 250 Hz)."""
    from tests.test_unseen_robot_kinds import quiet
    from tests.test_unseen_robot_labs import write_records

    urdf, _, files, _ = write_records(DAYS_LAB, tmp_path)
    in_days(files["train"])
    code, message = quiet(["identify", "--urdf", str(urdf), "--data", str(files["train"]), "--out",
                           str(tmp_path / "result.json")])
    assert code == 2 and "Traceback" not in message, message
    assert "look like days" in message and "--columns t=86400*t" in message, message


@pytest.mark.slow
def test_with_the_option_the_error_names_a_log_in_days_predicts_as_well_as_a_plain_fit(tmp_path):
    """The three records' time in days: the option the error names (``--columns t=86400*t``) given to every verb,
    and the result as good as the plain fit's on the log in seconds; ``oed predict`` reproduces each reported
    validation error."""
    from tests.test_one_answer_audit import RELATIVE
    from tests.test_unseen_robot_kinds import as_well_as_the_plain_fit
    from tests.test_unseen_robot_labs import run_lab

    outcome = run_lab(DAYS_LAB, tmp_path, rewritten=in_days, reading=("--columns", "t=86400*t"),
                      seconds=lambda stamps: stamps - 86400.0 * SERIAL)
    as_well_as_the_plain_fit(f"{DAYS_LAB.name}, read with --columns t=86400*t", outcome,
                             f"chosen {outcome['selections']}; ")
    for label, error in outcome["reproduced"].items():
        assert error < RELATIVE, (label, error)
