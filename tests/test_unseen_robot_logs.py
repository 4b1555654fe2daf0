"""Logs as other labs' loggers write them (issue 34), beside :mod:`tests.test_unseen_robot_labs`: the same
simulated robots and records, the files rewritten the way a logger writes them (h-unseen5)."""

from __future__ import annotations

import dataclasses
import json
import re
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.urdf_export import robot_urdf
from tests.test_one_answer_audit import RELATIVE
from tests.test_unseen_robot_kinds import as_well_as_the_plain_fit, marks, quiet
from tests.test_unseen_robot_labs import Lab, puma, verbs_against_the_plain_fit, write_records
from tests.test_unseen_robots import FRICTION, Log, truth

Rewrite = Callable[[pd.DataFrame, str], pd.DataFrame]


@dataclass(frozen=True)
class LoggedAs:
    name: str
    lab: Lab
    rewrite: Rewrite | None = None  # the table as the logger writes it, per role
    options: tuple[str, ...] = ()  # what the user declares to identify and diagnose
    reading: tuple[str, ...] = ()  # and to every verb: how the log reads (--columns)
    slow: bool = False
    xfail: str = ""
    urdf: Callable[[str], str] | None = None  # the lab's description as given (the simulation's rewritten)
    seconds: Callable[[np.ndarray], np.ndarray] = lambda t: t  # the predictions' time stamps, as the simulation's


def run_logged(case: LoggedAs, folder: Path) -> dict:
    from benchmarks.bench_real_robots import PlainFit

    urdf, records, files, spread = write_records(case.lab, folder)
    if case.rewrite is not None:
        for role, path in files.items():
            written = case.rewrite(pd.read_csv(path), role)
            written.to_csv(path, index=False, float_format="%.17g")
            stamps = written["t"] if "t" in written.columns else None
            if stamps is not None and len(written) == records[role].t.shape[0]:  # the plain fit reads them too
                records[role] = dataclasses.replace(records[role], t=case.seconds(stamps.to_numpy(dtype=float)))
    plain = PlainFit(["--urdf", str(urdf)])
    if case.urdf is not None:
        simulated = folder / "simulated.urdf"
        simulated.write_text(urdf.read_text())
        plain = PlainFit(["--urdf", str(simulated)])
        urdf.write_text(case.urdf(urdf.read_text()))
    rate = min(log.rate_hz for log in (case.lab.train, case.lab.validate, case.lab.test))
    cutoff, plain_theta = plain.fit(records["train"], records["validate"], rate_hz=rate)
    test = records["test"]
    predicted_plain, kept = plain.predict(test, cutoff, plain_theta)
    written = pd.read_csv(files["test"])
    if len(written) == kept.shape[0]:  # scored where the test file holds torques (a channel at a lower rate)
        kept = kept & written[[name for name in written.columns if name.startswith("tau")]].notna().all(axis=1).to_numpy()
    outcome = verbs_against_the_plain_fit(urdf, files, test, kept, predicted_plain, folder, options=case.options,
                                          reading=case.reading, seconds=case.seconds)
    return {**outcome, "cutoff": cutoff, "floor": (0.02 * spread) ** 2}


def lab(name: str, train: float = 8.0) -> Lab:
    """The PUMA's first 3 joints, 250 Hz, no logged velocity: training ``train`` s, validation 3 s, test 5 s."""
    return Lab(name, puma(3), Log(train, 250.0, velocity=False), Log(3.0, 250.0, velocity=False),
               Log(5.0, 250.0, velocity=False))


EPOCH_NS = 1_764_240_000_000_000_000  # 27 Nov 2025 in nanoseconds since 1970: a ROS stamp


def nanoseconds_degrees_millinewton_metres(frame: pd.DataFrame, role: str) -> pd.DataFrame:
    """A logger's own names and units: stamps in ns since 1970, positions in degrees, torques in mN m."""
    out = pd.DataFrame({"stamp_ns": np.round(frame["t"].to_numpy() * 1e9).astype(np.int64) + EPOCH_NS})
    for name in frame.columns:
        if name.startswith("q"):
            out[f"pos_deg{name[1:]}"] = np.degrees(frame[name])
    for name in frame.columns:
        if name.startswith("tau"):
            out[f"torque_mNm{name[3:]}"] = 1e3 * frame[name]
    return out


def clock_not_at_zero(frame: pd.DataFrame, role: str) -> pd.DataFrame:
    return frame.assign(t=frame["t"] + 5321.25)


def float32_clock(start: float) -> Rewrite:
    """Stamps of a clock started ``start`` s earlier (time since boot), stored as float32: rounded to 2⁻²³ of their
    size (0.24 ms at 3000 s, 3.9 ms at 40 000 s, about the 4 ms sampling step)."""
    return lambda frame, role: frame.assign(t=(frame["t"] + start).astype(np.float32).astype(float))


def velocity_in_degrees(frame: pd.DataFrame, role: str) -> pd.DataFrame:
    """The logged velocity in deg/s beside positions in rad (not declared)."""
    return frame.assign(**{name: np.degrees(frame[name]) for name in frame.columns if name.startswith("dq")})


def numbered_from_zero(frame: pd.DataFrame, role: str) -> pd.DataFrame:
    """A ROS ``JointState`` export: ``time``, ``position_0..``, ``effort_0..`` (arrays numbered from 0)."""
    out = pd.DataFrame({"time": frame["t"]})
    for group, prefix in (("q", "position_"), ("tau", "effort_")):
        for name in frame.columns:
            if name.startswith(group) and name[len(group):].isdigit():
                out[f"{prefix}{int(name[len(group):]) - 1}"] = frame[name]
    return out


def torques_at_half_rate(frame: pd.DataFrame, role: str) -> pd.DataFrame:
    """Positions at 250 Hz and torques at 125 Hz merged into one table: the torque cells of every other row blank."""
    frame = frame.copy()
    frame.loc[frame.index % 2 == 1, [name for name in frame.columns if name.startswith("tau")]] = np.nan
    return frame


def continuous_base(text: str) -> str:
    """The description with joint 1 (about the vertical: the dynamics do not depend on its angle) continuous."""
    return re.sub(r'(<joint name="joint1" type=")revolute(">.*?)<limit[^>]*/>', r"\1continuous\2", text, count=1,
                  flags=re.S)


def wrapped_base(frame: pd.DataFrame, role: str) -> pd.DataFrame:
    """Joint 1 turned by 3 rad and logged wrapped to ±π (a continuous joint's angle as many drivers report it)."""
    return frame.assign(q1=np.angle(np.exp(1j * (frame["q1"] + 3.0))))


FINGERS = """
  <link name="finger_left"><inertial><origin xyz="0 0.01 0.02"/><mass value="0.05"/>
    <inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/></inertial></link>
  <joint name="finger_left_joint" type="prismatic"><origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>
    <parent link="joint3_link"/><child link="finger_left"/><limit lower="0" upper="0.04" velocity="0.2" effort="20"/>
  </joint>
  <link name="finger_right"><inertial><origin xyz="0 -0.01 0.02"/><mass value="0.05"/>
    <inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/></inertial></link>
  <joint name="finger_right_joint" type="prismatic"><origin xyz="0 0 0.1"/><axis xyz="0 -1 0"/>
    <parent link="joint3_link"/><child link="finger_right"/><limit lower="0" upper="0.04" velocity="0.2" effort="20"/>
    MIMIC</joint>
</robot>"""


def gripper(mimic: bool) -> Callable[[str], str]:
    """The arm's description with a parallel gripper at its flange: two prismatic fingers (0.05 kg each, closed at
    0), the right one a ``<mimic>`` of the left when ``mimic``; the log holds the arm's joints only."""
    tag = '<mimic joint="finger_left_joint"/>' if mimic else ""
    return lambda text: text.replace("</robot>", FINGERS.replace("MIMIC", tag))


ARM = ("--joint-names", "joint1,joint2,joint3")
LOGS = (
    LoggedAs("stamps in ns since 1970, positions in degrees, torques in mN m, declared by --columns",
             lab("units"), nanoseconds_degrees_millinewton_metres,
             reading=("--columns", "t=1e-9*stamp_ns,q=0.017453292519943295*pos_deg,tau=0.001*torque_mNm"),
             seconds=lambda t: t - EPOCH_NS * 1e-9, slow=True),
    LoggedAs("a ROS JointState export, its arrays numbered from 0, declared by --columns", lab("ros"),
             numbered_from_zero, reading=("--columns", "t=time,q=position_,tau=effort_"), slow=True),
    LoggedAs("100 000 samples: 400 s at 250 Hz of training", Lab("long", puma(3), Log(400.0, 250.0, velocity=False),
                                                                 Log(3.0, 250.0, velocity=False),
                                                                 Log(5.0, 250.0, velocity=False)), slow=True),
    LoggedAs("a clock that starts at 5321.25 s", lab("clock"), clock_not_at_zero, seconds=lambda t: t - 5321.25),
    LoggedAs("a float32 clock at 3000 s (stamps rounded to 0.24 ms)", lab("f32"), float32_clock(3000.0),
             seconds=lambda t: t - 3000.0, slow=True),
    # at 2878a20 joint 3 was 2.2x the plain fit (the torques filtered); with the torques fitted as recorded (b4dc7c8)
    # 0.014 / 0.037 / 1.044 of it, 0.030 in total; the time base is still lost (said: CoarseStampsWarning)
    LoggedAs("a float32 clock at 40 000 s (stamps rounded to 3.9 ms, the step 4 ms)", lab("f32"),
             float32_clock(40000.0), seconds=lambda t: t - 40000.0, slow=True),
    LoggedAs("a logged velocity in deg/s beside positions in rad, undeclared", Lab(
        "dq", puma(3), Log(8.0, 250.0), Log(3.0, 250.0), Log(5.0, 250.0)), velocity_in_degrees, slow=True),
    LoggedAs("torques at 125 Hz beside positions at 250 Hz (blank torque cells)", lab("rates"), torques_at_half_rate,
             slow=True),
    LoggedAs("a gripper's fingers in the URDF, not in the log, --joint-names given", lab("fingers"),
             urdf=gripper(False), options=ARM, slow=True),
    LoggedAs("a gripper's mimic fingers in the URDF, not in the log, --joint-names given", lab("mimic"),
             urdf=gripper(True), options=ARM, slow=True),
    # at 2878a20 both exited (serial chains only; a <mimic> joint refused) where --joint-names joint1,joint2,joint3
    # ran; now the log's 3 joints determine that chain, the fingers held fixed (LoggedChainWarning)
    LoggedAs("a gripper's fingers in the URDF, not in the log, on the defaults", lab("fingers"), urdf=gripper(False)),
    # the mimic gripper on the defaults runs in ``make test-slow``: ``make test`` keeps the branching gripper on the
    # defaults here (the same arm, its fingers held fixed and merged alike) and reads the mimic chain on the defaults
    # in tests/test_logged_chain.py (the answer told by --joint-names, predict the same)
    LoggedAs("a gripper's mimic fingers in the URDF, not in the log, on the defaults", lab("mimic"),
             urdf=gripper(True), slow=True),
    # at 2878a20 both verbs ran and predicted garbage (joint 1 2382x and 2664x the plain fit: the jumps of 2π
    # differentiated); now the angle is unwrapped on reading, in memory and streamed alike (UnwrappedAngleWarning)
    LoggedAs("a continuous base joint logged wrapped to ±π", lab("wrap"), wrapped_base, urdf=continuous_base),
    # at 2878a20 identify (told coulomb and offset) exited: "the data do not determine fc2 and off2". The whole
    # record determines them (joint 2 reverses in its last fifth only: fc2 2.06 ± 0.03 with --method ols); the
    # weighting's held-out fit on the other four fifths did not, and ended the run on a choice of the toolkit's own.
    # Now that block is scored by neither weighting, said (HeldOutBlocksWarning): identify 1.192 / 1.068 / 0.284 x
    # the plain fit, 0.811 total; diagnose 0.977 / 0.987 / 0.328, 0.733 (h-xfail3)
    LoggedAs("1.5 s training and validation records", lab("short", train=1.5), slow=True),
)


@pytest.mark.parametrize("case", [pytest.param(case, id=case.name, marks=marks(case)) for case in LOGS])
def test_the_defaults_run_and_predict_a_log_as_its_logger_wrote_it(case, tmp_path):
    outcome = run_logged(case, tmp_path)
    as_well_as_the_plain_fit(case.name, outcome, f"chosen {outcome['selections']}; ")
    for label, error in outcome["reproduced"].items():
        assert error <= RELATIVE, (label, error)


def test_a_clock_that_restarts_is_named_with_the_segments_that_read_it(tmp_path):
    """One step back in the time stamps (a logger restarted): the message says so and names the segments; rows out
    of order in many places: sort them."""
    from estimation.data import TimeBaseError
    from estimation.data.records import read_measurements
    from tests.test_unseen_robots import urdf_of, write_record

    urdf = urdf_of("puma560:3", tmp_path)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    write_record(model, truth(model), Log(2.0, 250.0, velocity=False), 11, tmp_path / "clean.csv")
    table = pd.read_csv(tmp_path / "clean.csv")
    table.loc[250:, "t"] -= table["t"].iloc[250]
    table.to_csv(tmp_path / "restart.csv", index=False)
    with pytest.raises(TimeBaseError, match=r"decreases at row 250 .* only there: a logger whose clock restarted\? "
                                            r"Split the file at that row .*--data or --validate repeated"):
        read_measurements(tmp_path / "restart.csv", model=model)
    table = pd.read_csv(tmp_path / "clean.csv").sample(frac=1.0, random_state=0)
    table.to_csv(tmp_path / "shuffled.csv", index=False)
    with pytest.raises(TimeBaseError, match="other row.*; sort the samples"):
        read_measurements(tmp_path / "shuffled.csv", model=model)


def test_torques_logged_at_a_lower_rate_are_read_alike_in_memory_and_streamed(tmp_path):
    """Torque cells blank on every other row (a channel at half the rate, merged): those rows dropped with a warning
    (the positions there with them), in memory and chunk by chunk alike; a torque column blank throughout stays an
    error naming it."""
    from estimation.data import BlankRowsWarning, NonFiniteError
    from estimation.data.records import read_measurements
    from estimation.streaming.chunks import read_chunks
    from tests.test_unseen_robots import urdf_of, write_record

    urdf = urdf_of("puma560:3", tmp_path)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    write_record(model, truth(model), Log(4.0, 250.0, velocity=False), 11, tmp_path / "clean.csv")
    table = torques_at_half_rate(pd.read_csv(tmp_path / "clean.csv"), "train")
    table.to_csv(tmp_path / "rates.csv", index=False)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        memory = read_measurements(tmp_path / "rates.csv", model=model)
        chunks = list(read_chunks(tmp_path / "rates.csv", model, chunk_size=250))
    said = [str(item.message) for item in caught if issubclass(item.category, BlankRowsWarning)]
    assert len(said) == 2 and all("dropped 500 row(s)" in text for text in said), "\n".join(said)
    kept = np.arange(0, len(table), 2)
    assert np.array_equal(memory.as_recorded.t, table["t"].to_numpy()[kept])
    assert np.array_equal(memory.as_recorded.tau, table[["tau1", "tau2", "tau3"]].to_numpy()[kept])
    assert np.allclose(np.concatenate([chunk.t for chunk in chunks]), memory.t, rtol=0, atol=1e-12)
    assert np.allclose(np.vstack([chunk.tau for chunk in chunks]), memory.tau, rtol=0, atol=1e-12)
    table["tau2"] = np.nan  # never logged
    table.to_csv(tmp_path / "never.csv", index=False)
    with pytest.raises(NonFiniteError, match="column tau2"), warnings.catch_warnings():
        warnings.simplefilter("ignore", BlankRowsWarning)
        read_measurements(tmp_path / "never.csv", model=model)


def test_a_branching_description_names_the_joint_names_that_read_it(tmp_path):
    from dynamics.errors import RobotDescriptionError

    path = tmp_path / "gripper.urdf"
    path.write_text(gripper(False)(robot_urdf(load_robot("puma560", joints=3))))
    with pytest.raises(RobotDescriptionError, match="--joint-names joint1,joint2,joint3"):
        load_robot(urdf=path)


def test_a_joint_held_still_is_named_with_the_lock_that_leaves_it_out(tmp_path):
    """Joint 2 held by its brake through the record: a warning names it and the options that lock it (measured at
    2878a20 on a 3-joint PUMA log: both verbs exit on the rank-deficiency error, naming mx2R, off2 / Izz1R, Ixx2R,
    Ixy2 and not the joint)."""
    from estimation.data import StillJointWarning
    from estimation.data.records import read_measurements
    from tests.test_unseen_robots import urdf_of, write_record

    urdf = urdf_of("puma560:3", tmp_path)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    write_record(model, truth(model), Log(2.0, 250.0, velocity=False), 11, tmp_path / "clean.csv")
    pd.read_csv(tmp_path / "clean.csv").assign(q2=0.35).to_csv(tmp_path / "still.csv", index=False)
    with pytest.warns(StillJointWarning, match=r"joint joint2 does not move \(q2 = 0.35 on every row\).*"
                                               r"--joint-names joint1,joint3 --locked-at joint2=0.35"):
        read_measurements(tmp_path / "still.csv", model=model)
    with warnings.catch_warnings():
        warnings.simplefilter("error", StillJointWarning)
        read_measurements(tmp_path / "clean.csv", model=model)


def test_joints_numbered_from_zero_are_named_with_the_map_that_reads_them(tmp_path):
    """``q0..q2``, ``tau0..tau2`` (a log numbered as Python arrays): the message names the map, and the map reads the
    columns as joints 1 to 3."""
    from estimation.data import MissingColumnError
    from estimation.data.log_formats import LogSource
    from estimation.data.records import read_measurements
    from tests.test_unseen_robots import urdf_of, write_record

    urdf = urdf_of("puma560:3", tmp_path)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    write_record(model, truth(model), Log(2.0, 250.0, velocity=False), 11, tmp_path / "clean.csv")
    clean = pd.read_csv(tmp_path / "clean.csv")
    clean.rename(columns=lambda name: name if name == "t" else f"{name.rstrip('0123456789')}{int(name[-1]) - 1}"
                 ).to_csv(tmp_path / "zero.csv", index=False)
    with pytest.raises(MissingColumnError, match=r"numbers its joints from 0 \(q0, tau0\).*--columns q=q,tau=tau"):
        read_measurements(tmp_path / "zero.csv", model=model)
    read = read_measurements(LogSource(tmp_path / "zero.csv", columns={"q": "q", "tau": "tau"}), model=model)
    assert np.array_equal(read.as_recorded.q if read.as_recorded is not None else read.q,
                          clean[["q1", "q2", "q3"]].to_numpy())


def test_an_angle_wrapped_to_half_a_turn_is_unwrapped_in_memory_and_streamed_alike(tmp_path):
    """Measured at 2878a20: both verbs ran on the wrapped log and predicted garbage (joint 1 2382x the plain fit); at
    a37ea65 refused (WrappedAngleError). Now unwrapped on reading with a warning naming the joint and the wraps: in
    memory as numpy.unwrap gives it, and streamed with a chunk edge at a wrap identical to the last bit."""
    from estimation.data import UnwrappedAngleWarning, WrappedAngleError
    from estimation.data.records import read_measurements
    from estimation.streaming.chunks import read_chunks
    from tests.test_unseen_robots import write_record

    simulated = build_model(load_robot("puma560", joints=3), "internal", FRICTION)
    write_record(simulated, truth(simulated), Log(4.0, 250.0, velocity=False), 11, tmp_path / "clean.csv")
    urdf = tmp_path / "robot.urdf"
    urdf.write_text(continuous_base(robot_urdf(load_robot("puma560", joints=3))))
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    clean = pd.read_csv(tmp_path / "clean.csv")
    wrapped = wrapped_base(clean, "train")
    wrapped.to_csv(tmp_path / "wrapped.csv", index=False, float_format="%.17g")
    logged = wrapped["q1"].to_numpy()
    jumps = np.flatnonzero(np.abs(np.diff(logged)) > np.pi) + 1
    assert jumps.size >= 1
    with pytest.warns(UnwrappedAngleWarning, match=rf"joint1 \(q1\): {jumps.size} wrap\(s\)"):
        read = read_measurements(tmp_path / "wrapped.csv", model=model)
    q = read.as_recorded.q if read.as_recorded is not None else read.q
    assert np.allclose(q[:, 0], np.unwrap(logged), atol=1e-12, rtol=0)
    assert np.allclose(q[:, 0], clean["q1"].to_numpy() + 3.0 - 2 * np.pi * round((3.0 + clean["q1"][0] - logged[0])
                                                                                  / (2 * np.pi)), atol=1e-9)
    assert np.array_equal(q[:, 1:], wrapped[["q2", "q3"]].to_numpy())
    size = next(c for c in range(model.n_base + 1, int(jumps[0]) + 1) if int(jumps[0]) % c == 0)
    with pytest.warns(UnwrappedAngleWarning, match=rf"joint1 \(q1\): {jumps.size} wrap\(s\)"):
        chunks = list(read_chunks(tmp_path / "wrapped.csv", model, chunk_size=size))
    assert len(chunks) > 2 and any(read.t[int(jumps[0])] == chunk.t[0] for chunk in chunks)  # an edge at the wrap
    for name in ("t", "q", "tau"):
        assert np.array_equal(np.concatenate([getattr(chunk, name) for chunk in chunks]), getattr(read, name)), name

    # a whole turn on a limited joint away from ±π (an encoder glitch) is not a wrap: the message stays
    glitch = clean.assign(q2=clean["q2"] + np.where(np.arange(len(clean)) >= 500, 2 * np.pi, 0.0))
    glitch.to_csv(tmp_path / "glitch.csv", index=False)
    limited = build_model(load_robot(urdf=_limited(tmp_path)), "internal", FRICTION)
    with pytest.raises(WrappedAngleError, match=r"column q2 jumps .* a whole turn.*not a wrap.*numpy.unwrap"):
        read_measurements(tmp_path / "glitch.csv", model=limited)
    with pytest.raises(WrappedAngleError, match="column q2 jumps"):
        list(read_chunks(tmp_path / "glitch.csv", limited, chunk_size=250))
    # joint 1 revolute with limits past ±π: unwrapped while the angle stays within them, refused once it would leave
    for limit, refused in ((3.5, False), (float(np.max(np.abs(q[:, 0]))) - 0.2, True)):
        urdf.write_text(re.sub(r'(<joint name="joint1" type="revolute">.*?)<limit[^>]*/>',
                               rf'\1<limit lower="{-limit}" upper="{limit}" velocity="5" effort="200"/>',
                               robot_urdf(load_robot("puma560", joints=3)), count=1, flags=re.S))
        bounded = build_model(load_robot(urdf=urdf), "internal", FRICTION)
        if refused:
            with pytest.raises(WrappedAngleError, match=r"column q1 jumps .* leave the joint's limits.*numpy.unwrap"):
                read_measurements(tmp_path / "wrapped.csv", model=bounded)
        else:
            with pytest.warns(UnwrappedAngleWarning):
                assert np.array_equal(read_measurements(tmp_path / "wrapped.csv", model=bounded).q, read.q)
    read_measurements(tmp_path / "clean.csv", model=model)


def test_a_wrapped_angle_is_read_by_identify_streamed_and_by_predict_as_unwrapped(tmp_path):
    """``oed identify`` in memory and streamed (chunks of 200 rows, wraps inside and at chunk edges) give the same fit
    of the wrapped log; ``oed predict`` on the wrapped record predicts what it predicts on the record unwrapped."""
    from tests.test_unseen_robots import write_record

    simulated = build_model(load_robot("puma560", joints=3), "internal", FRICTION)
    for role, seed in (("train", 11), ("validate", 12)):
        write_record(simulated, truth(simulated), Log(4.0, 250.0, velocity=False), seed, tmp_path / f"{role}_.csv")
        wrapped = wrapped_base(pd.read_csv(tmp_path / f"{role}_.csv"), role)
        wrapped.to_csv(tmp_path / f"{role}.csv", index=False, float_format="%.17g")
        wrapped.assign(q1=np.unwrap(wrapped["q1"].to_numpy())).to_csv(tmp_path / f"{role}_unwrapped.csv",
                                                                         index=False, float_format="%.17g")
    urdf = tmp_path / "robot.urdf"
    urdf.write_text(continuous_base(robot_urdf(load_robot("puma560", joints=3))))
    fits = {}
    for label, more in (("memory", []), ("streamed", ["--chunk-size", "200"])):
        code, message = quiet(["identify", "--urdf", str(urdf), "--data", str(tmp_path / "train.csv"), "--validate",
                               str(tmp_path / "validate.csv"), "--friction", FRICTION, *more,
                               "--out", str(tmp_path / f"{label}.json")])
        assert code == 0, message
        assert "joint1 (q1): " in message and "wrap(s)" in message, message
        fits[label] = json.loads((tmp_path / f"{label}.json").read_text())["validation"]["mse"]
    for channel, mse in fits["memory"].items():
        assert abs(fits["streamed"][channel] - mse) <= 1e-8 * mse, (channel, fits)
    predicted = {}
    for label in ("validate", "validate_unwrapped"):
        code, message = quiet(["predict", "--model", str(tmp_path / "memory.json"), "--data",
                               str(tmp_path / f"{label}.csv"), "--out", str(tmp_path / f"{label}_predicted.csv")])
        assert code == 0, message
        predicted[label] = pd.read_csv(tmp_path / f"{label}_predicted.csv")
    columns = [name for name in predicted["validate"].columns if name.startswith("tau")]
    assert columns and np.allclose(predicted["validate"][columns], predicted["validate_unwrapped"][columns],
                                   rtol=1e-9, atol=1e-9)


def _limited(folder: Path) -> Path:
    """The PUMA's first three joints with limits of ±2.5 rad on each."""
    text = robot_urdf(load_robot("puma560", joints=3))
    text = re.sub(r'<limit[^>]*/>', '<limit lower="-2.5" upper="2.5" velocity="5" effort="200"/>', text)
    if "<limit" not in text:
        text = re.sub(r'(<joint name="joint\d" type="revolute">)', r'\1<limit lower="-2.5" upper="2.5" '
                      r'velocity="5" effort="200"/>', text)
    path = folder / "limited.urdf"
    path.write_text(text)
    return path


def test_a_units_row_and_a_comment_line_are_named(tmp_path):
    """A second header line of units beneath the names: refused, saying so (a units row naming the format's SI units
    is skipped and said, h-unseen7); a comment line above them: skipped and said (h-logs5)."""
    from estimation.data import CommentLinesWarning, NonFiniteError, UnitsRowWarning
    from estimation.data.records import read_measurements
    from tests.test_unseen_robots import urdf_of, write_record

    urdf = urdf_of("puma560:3", tmp_path)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    write_record(model, truth(model), Log(2.0, 250.0, velocity=False), 11, tmp_path / "clean.csv")
    clean = pd.read_csv(tmp_path / "clean.csv")
    units = pd.DataFrame([["s", "rad", "rad", "rad", "N m", "N m", "N m"]], columns=clean.columns)
    pd.concat([units, clean]).to_csv(tmp_path / "units.csv", index=False)
    with pytest.warns(UnitsRowWarning, match="s,rad,rad,rad,N m,N m,N m"):
        read_measurements(tmp_path / "units.csv", model=model)
    units = pd.DataFrame([["s", "rad", "rad", "rad", "A", "A", "A"]], columns=clean.columns)  # currents (h-unseen12:
    pd.concat([units, clean]).to_csv(tmp_path / "currents.csv", index=False)  # deg, mN·m are converted)
    with pytest.raises(NonFiniteError, match=r"a second header line \(units\?\) beneath the names"):
        read_measurements(tmp_path / "currents.csv", model=model)
    (tmp_path / "comment.csv").write_text("# rig 3, 27 Nov\n" + (tmp_path / "clean.csv").read_text())
    with pytest.warns(CommentLinesWarning, match="its first 1 line"):  # refused (MissingColumnError) before h-logs5
        commented = read_measurements(tmp_path / "comment.csv", model=model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert np.array_equal(commented.q, read_measurements(tmp_path / "clean.csv", model=model).q)


def test_float32_stamps_rounded_to_about_the_step_are_said(tmp_path):
    """A float32 clock at 40 000 s (rounded to 3.9 ms, the step 4 ms): a :class:`CoarseStampsWarning`; at 3000 s
    (0.24 ms) none."""
    from estimation.data import CoarseStampsWarning
    from estimation.data.records import read_measurements
    from tests.test_unseen_robots import urdf_of, write_record

    urdf = urdf_of("puma560:3", tmp_path)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    write_record(model, truth(model), Log(2.0, 250.0, velocity=False), 11, tmp_path / "clean.csv")
    clean = pd.read_csv(tmp_path / "clean.csv")
    float32_clock(40000.0)(clean, "train").to_csv(tmp_path / "far.csv", index=False, float_format="%.17g")
    float32_clock(3000.0)(clean, "train").to_csv(tmp_path / "near.csv", index=False, float_format="%.17g")
    for name, said in (("far.csv", True), ("near.csv", False)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            read_measurements(tmp_path / name, model=model)
        coarse = [str(item.message) for item in caught if issubclass(item.category, CoarseStampsWarning)]
        assert bool(coarse) == said, (name, coarse)
        assert all(re.search(r"rounded to 3.91 ms, \d+% of the sampling step", text) for text in coarse), coarse
