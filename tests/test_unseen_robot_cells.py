"""Work cells the project has not seen (issue 34), beside the other unseen-robot modules
(:mod:`tests.test_unseen_robots`, ``_kinds``, ``_realities``, ``_labs``, ``_logs``), run by the same harness
(:func:`tests.test_unseen_robot_logs.run_logged`):

- a SCARA described by a hand-written URDF: two revolute joints about the vertical (no gravity on them), a
  prismatic quill moving along the vertical (its gravity load a constant, the same column as its offset) and a
  roll joint carrying a tool off its axis;
- a URDF whose inertials are placeholders (every link 1 kg at its frame's origin, identity inertia), so the
  description's prior is far from the truth;
- a training record at rest for half its length (the robot stopped in the middle of the excitation);
- torque sensors whose bias drifts as they warm up (different in each record);
- logs as labs write them (h-unseen7): columns named by joint (``shoulder_pan_joint_effort``), the time as
  ``time [ms]``, ``;`` separators with ``,`` decimals, a units row, repeated time stamps, 100 Hz only; a vendor-style
  URDF (fixed joints and frame links between the moving ones, a tool frame); a light wrist under sensors of equal
  absolute noise; a test record far outside one joint's training range, with the description's bodies 20 % off or
  from CAD without motors (h-extrap; a strict xfail until the simulated truth was drawn in the URDF's frames).

No data are copied; every record is simulated (the plain fit's model class, :func:`tests.test_unseen_robots.truth`,
white torque noise of 2 % of each channel's spread). Each case runs the default ``oed identify`` (told the plain
fit's model class) and ``oed diagnose`` (its own defaults), then ``oed predict`` on a test record no choice saw,
against the plain Pinocchio least-squares fit of ``benchmarks/bench_real_robots.py`` (its cut-off chosen on the
validation record) on the same recorded samples: per joint within 1.3x, in total at most 1.0x, each figure allowed
its noise floor's sampling spread; and ``oed predict`` on the validation record reproduces the validation error each
verb reported (relative 1e-6)."""

from __future__ import annotations

import re
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dynamics.robots import load_robot
from tests.test_one_answer_audit import RELATIVE
from tests.test_unseen_robot_kinds import as_well_as_the_plain_fit, marks, ur10e
from tests.test_unseen_robot_labs import Lab, puma
from tests.test_unseen_robot_logs import EPOCH_NS, LoggedAs, run_logged
from tests.test_unseen_robots import Log

#: a SCARA of a 0.6 m reach (the published lengths of a mid-size one: 0.325 + 0.275 m, a 0.2 m quill), link masses
#: split by hand; the roll joint carries a 1 kg tool off its axis
SCARA = """<?xml version="1.0"?>
<robot name="scara">
  <link name="world"/>
  <joint name="pedestal" type="fixed"><origin xyz="0 0 0.2"/><parent link="world"/><child link="base"/></joint>
  <link name="base"><inertial><origin xyz="0 0 0.1"/><mass value="15"/><inertia ixx="0.2" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.1"/></inertial></link>
  <joint name="shoulder" type="revolute"><origin xyz="0 0 0.25"/><axis xyz="0 0 1"/><parent link="base"/><child link="arm1"/>
    <limit lower="-2.6" upper="2.6" velocity="3.0" effort="200"/></joint>
  <link name="arm1"><inertial><origin xyz="0.16 0 0.03"/><mass value="7.5"/><inertia ixx="0.02" ixy="0" ixz="0.001" iyy="0.09" iyz="0" izz="0.085"/></inertial></link>
  <joint name="elbow" type="revolute"><origin xyz="0.325 0 0.05"/><axis xyz="0 0 1"/><parent link="arm1"/><child link="arm2"/>
    <limit lower="-2.5" upper="2.5" velocity="4.0" effort="100"/></joint>
  <link name="arm2"><inertial><origin xyz="0.14 0.01 -0.02"/><mass value="5.0"/><inertia ixx="0.01" ixy="0.001" ixz="0" iyy="0.045" iyz="0" izz="0.042"/></inertial></link>
  <joint name="quill" type="prismatic"><origin xyz="0.275 0 0"/><axis xyz="0 0 -1"/><parent link="arm2"/><child link="spline"/>
    <limit lower="0" upper="0.2" velocity="0.5" effort="300"/></joint>
  <link name="spline"><inertial><origin xyz="0 0 0.1"/><mass value="1.2"/><inertia ixx="0.005" ixy="0" ixz="0" iyy="0.005" iyz="0" izz="0.0003"/></inertial></link>
  <joint name="roll" type="revolute"><origin xyz="0 0 -0.05"/><axis xyz="0 0 1"/><parent link="spline"/><child link="flange"/>
    <limit lower="-3.0" upper="3.0" velocity="6.0" effort="12"/></joint>
  <link name="flange"><inertial><origin xyz="0 0 -0.01"/><mass value="0.3"/><inertia ixx="0.0002" ixy="0" ixz="0" iyy="0.0002" iyz="0" izz="0.0002"/></inertial></link>
  <joint name="tool_mount" type="fixed"><origin xyz="0.04 0.01 -0.03"/><parent link="flange"/><child link="tool"/></joint>
  <link name="tool"><inertial><origin xyz="0 0 -0.02"/><mass value="1.0"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.0008"/></inertial></link>
</robot>
"""


def scara() -> object:
    """The SCARA as the simulation's robot (read from :data:`SCARA`)."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "scara.urdf"
        path.write_text(SCARA)
        return load_robot(urdf=path)


def as_written(text: str) -> str:
    """The description the lab hands over: :data:`SCARA` as written (a world link, fixed pedestal and tool)."""
    del text
    return SCARA


def placeholders(text: str) -> str:
    """Every link's inertial a placeholder: 1 kg at the link frame's origin, identity inertia."""
    text = re.sub(r'<mass value="[^"]*"\s*/>', '<mass value="1.0" />', text)
    text = re.sub(r'(<inertial>\s*<origin xyz=")[^"]*(")', r"\g<1>0 0 0\2", text)
    return re.sub(r"<inertia [^>]*/>", '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1" />', text)


#: the UR10e's joints as Universal Robots' driver names them, and the order its /joint_states messages list them
UR_NAMES = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
            "wrist_3_joint")
PUBLISHED = (2, 1, 0, 3, 4, 5)  # elbow, shoulder lift, shoulder pan, wrist 1-3: the driver's alphabetical order


def ur_names(text: str) -> str:
    """The description with the driver's joint names."""
    for index, name in enumerate(UR_NAMES):
        text = text.replace(f'"ur_joint{index + 1}"', f'"{name}"')
    return text


def rostopic_echo(frame: pd.DataFrame, role: str) -> pd.DataFrame:
    """``rostopic echo -p /joint_states`` of a UR driver's messages: ``%time`` (ns since 1970, when the topic was
    logged: 2 ms after the stamp), the header (its stamp the sampling time), the names
    ``field.name0..`` and ``field.position0..``, ``field.velocity0..``, ``field.effort0..`` in the order the
    messages list the joints (:data:`PUBLISHED`), not the description's."""
    n = len(PUBLISHED)
    stamps = np.round(frame["t"].to_numpy() * 1e9).astype(np.int64) + EPOCH_NS
    out = {"%time": stamps + 2_000_000, "field.header.seq": np.arange(len(frame)), "field.header.stamp": stamps,
           "field.header.frame_id": ""}
    out.update({f"field.name{k}": UR_NAMES[PUBLISHED[k]] for k in range(n)})
    for group, prefix in (("q", "field.position"), ("dq", "field.velocity"), ("tau", "field.effort")):
        if f"{group}1" in frame.columns:
            out.update({f"{prefix}{k}": frame[f"{group}{PUBLISHED[k] + 1}"].to_numpy() for k in range(n)})
    return pd.DataFrame(out)


def named_by_joint_in_ms(frame: pd.DataFrame, role: str) -> pd.DataFrame:
    """:func:`named_by_joint` with its time as ``time [ms]`` (milliseconds), no ``t`` column."""
    out = named_by_joint(frame, role)
    return out.drop(columns="t").assign(**{"time [ms]": 1e3 * frame["t"].to_numpy()})[
        ["time [ms]", *[name for name in out.columns if name != "t"]]]


def fixed_between(text: str) -> str:
    """The description as a vendor's URDF writes it: each moving joint's placement on a fixed joint to a frame link
    of its own (``<parent>_mount``, no inertial), the moving joint at that frame's origin; a massless ``flange`` and
    ``tool0`` on fixed joints after the last link (the same kinematics and bodies)."""
    pattern = re.compile(r'<joint name="(?P<name>[^"]+)" type="(?P<type>revolute|prismatic|continuous)">\s*'
                         r'<origin (?P<origin>[^/]*)/>\s*<parent link="(?P<parent>[^"]+)" />')

    def mounted(found: re.Match) -> str:
        name, parent = found["name"], found["parent"]
        return (f'<joint name="{name}_mount_fixed" type="fixed"><origin {found["origin"]}/><parent link="{parent}" />'
                f'<child link="{name}_mount" /></joint>\n  <link name="{name}_mount" />\n  '
                f'<joint name="{name}" type="{found["type"]}">\n    <origin xyz="0 0 0" rpy="0 0 0" />\n    '
                f'<parent link="{name}_mount" />')

    text, count = pattern.subn(mounted, text)
    assert count == 6, count
    last = re.findall(r'<child link="([^"]+)" />', text)[-1]
    tool = (f'<joint name="flange_fixed" type="fixed"><origin xyz="0 0 0.1" rpy="0 -1.5708 0" /><parent link="{last}" />'
            '<child link="flange" /></joint>\n  <link name="flange" />\n  <joint name="tool0_fixed" type="fixed">'
            '<origin xyz="0 0 0.05" rpy="0 0 0.7854" /><parent link="flange" /><child link="tool0" /></joint>\n  '
            '<link name="tool0" />\n</robot>')
    return text.replace("</robot>", tool)


def named_by_joint(frame: pd.DataFrame, role: str) -> pd.DataFrame:
    """A lab's own CSV export: ``t``, then per joint ``<joint>_position``, ``_velocity``, ``_effort`` (the driver's
    joint names, :data:`UR_NAMES`), the joints in the driver's order (:data:`PUBLISHED`), no ``q1..``/``tau1..``."""
    out = {"t": frame["t"].to_numpy()}
    for group, word in (("q", "position"), ("dq", "velocity"), ("tau", "effort")):
        for k in PUBLISHED:
            if f"{group}{k + 1}" in frame.columns:
                out[f"{UR_NAMES[k]}_{word}"] = frame[f"{group}{k + 1}"].to_numpy()
    return pd.DataFrame(out)


def clock_not_ticking(frame: pd.DataFrame, role: str) -> pd.DataFrame:
    """A logger whose clock did not tick now and then: 0.5 % of the rows (none adjacent) stamped with the previous
    row's time, each row holding its own sample."""
    generator = np.random.default_rng({"train": 1, "validate": 2, "test": 3}[role])
    rows = generator.choice(np.arange(5, len(frame) - 5, 3), max(1, len(frame) // 200), replace=False)
    t = frame["t"].to_numpy().copy()
    t[rows] = t[rows - 1]
    return frame.assign(t=t)


CELLS = (
    LoggedAs("SCARA from a hand-written URDF (vertical prismatic quill, a 1 kg tool on the roll joint), 10 s / 4 s / "
             "6 s at 250 Hz, no dq", Lab("scara", scara, *(Log(seconds, 250.0, velocity=False)
                                                          for seconds in (10.0, 4.0, 6.0))), urdf=as_written,
             slow=True),
    LoggedAs("UR10e-like, the URDF's inertials placeholders (1 kg at each frame, identity inertia), 10 s / 4 s / 6 s "
             "at 500 Hz, logged dq", Lab("placeholders", ur10e, *(Log(seconds, 500.0, motion_hz=0.1)
                                                                   for seconds in (10.0, 4.0, 6.0))),
             urdf=placeholders, slow=True),
    # (the case below at 35f0061, the holds cut from training only: diagnose 0.063/0.037/0.006/2.319/3.126/0.029x,
    # 1.057 total, no Coulomb law adopted on joints 4 and 5, the validation record's holds scored with the filter's
    # sign; now a hold's derivatives are zero wherever a record is derived)
    # a strict xfail at ad08589: identify 2.15/5.11/6.02/4.01/3.76/4.59x the plain fit, 4.11 total (20-198x the
    # noise floor), diagnose 4.14 total, the held positions' derived velocity switching the Coulomb columns; the
    # explicit --min-speed 0.02 gave the floor (identify and diagnose 0.96-1.09x it). Now the hold is cut out of the
    # training record (estimation.data.rest.holds, a HoldWarning)
    LoggedAs("PUMA 6 joints, the training record at rest for half its length (stopped mid-excitation), 16 s / 4 s / "
             "6 s at 250 Hz, no dq", Lab("halted", puma(6), *(Log(seconds, 250.0, velocity=False)
                                                             for seconds in (16.0, 4.0, 6.0)), halted=0.5),
             slow=True),
    LoggedAs("PUMA 6 joints, the training and validation records at rest for half their length, 16 s / 8 s / 6 s at "
             "250 Hz, no dq", Lab("halted twice", puma(6), *(Log(seconds, 250.0, velocity=False)
                                                            for seconds in (16.0, 8.0, 6.0)), halted=0.5,
                                   halted_in=("train", "validate")), slow=True),
    LoggedAs("PUMA 6 joints, torque sensors whose bias drifts as they warm (10 % of spread, 30 s time constant), "
             "12 s / 4 s / 6 s at 250 Hz, no dq", Lab("drift", puma(6), *(Log(seconds, 250.0, velocity=False)
                                                                         for seconds in (12.0, 4.0, 6.0)),
                                                    drift=0.1), slow=True),
    LoggedAs("UR10e-like logged by `rostopic echo -p /joint_states`: the driver's joint order (elbow first), the "
             "names in field.name0.., declared by --columns", Lab("rostopic", ur10e, *(Log(seconds, 500.0, motion_hz=0.1)
                                                                                      for seconds in (10.0, 4.0, 6.0))),
             rostopic_echo, urdf=ur_names, reading=("--columns", "t=1e-9*field.header.stamp,q=field.position,"
                                                                "dq=field.velocity,tau=field.effort"),
             seconds=lambda t: t - EPOCH_NS * 1e-9, slow=True),
    # at 4093904 both verbs exited on this table (missing column(s) t, q1..) where the --columns above worked
    LoggedAs("the same `rostopic echo -p` table on the defaults", Lab("rostopic", ur10e, *(
        Log(seconds, 500.0, motion_hz=0.1) for seconds in (10.0, 4.0, 6.0))), rostopic_echo, urdf=ur_names,
        seconds=lambda t: t - EPOCH_NS * 1e-9, slow=True),
    # at 7f2677d both verbs exited on this table (missing column(s) q1..) where --columns q1=shoulder_pan_joint_position,..
    # read it; now its columns are read by the robot's joint names (a JointNamedColumnsWarning gives the map)
    LoggedAs("UR10e-like, a lab's CSV whose columns are named by joint (shoulder_pan_joint_effort, ..., the driver's "
             "order), on the defaults", Lab("named", ur10e, *(Log(seconds, 500.0, motion_hz=0.1)
                                                              for seconds in (10.0, 4.0, 6.0))),
             named_by_joint, urdf=ur_names, slow=True),
    # at 7f2677d both verbs exited on it (missing column(s) t) where --columns t=0.001*time [ms],... read it
    LoggedAs("the same CSV with its time as `time [ms]`, on the defaults", Lab("named", ur10e, *(
        Log(seconds, 500.0, motion_hz=0.1) for seconds in (10.0, 4.0, 6.0))), named_by_joint_in_ms, urdf=ur_names,
        slow=True),
    LoggedAs("UR10e-like from a vendor-style URDF: a fixed joint and a frame link before each moving joint, a "
             "massless flange and tool0 on fixed joints, 10 s / 4 s / 6 s at 500 Hz, logged dq",
             Lab("fixed", ur10e, *(Log(seconds, 500.0, motion_hz=0.1) for seconds in (10.0, 4.0, 6.0))),
             urdf=fixed_between, slow=True),
    LoggedAs("UR10e-like logged at 100 Hz only (a ROS bag's rate), logged dq, 12 s / 4 s / 6 s",
             Lab("100 Hz", ur10e, *(Log(seconds, 100.0, motion_hz=0.1) for seconds in (12.0, 4.0, 6.0))), slow=True),
    LoggedAs("PUMA 6 joints, a light wrist (its friction at 2 %: 0.2-0.3 N m against 4-9 N m), torque sensors of equal absolute noise (2 % of the channels' mean spread: the wrist's "
             "signal-to-noise far below the shoulder's), 10 s / 4 s / 6 s at 250 Hz, no dq",
             Lab("equal noise", puma(6), *(Log(seconds, 250.0, velocity=False) for seconds in (10.0, 4.0, 6.0)),
                 friction_scale=(1.0, 1.0, 1.0, 0.02, 0.02, 0.02), equal_noise=True), slow=True),
    # the training and validation records hold joint 2 within -1.16..-1.01 rad, the test record -0.29..0.19 rad: no
    # record a choice saw measures the extrapolation. A strict xfail at 1a8e964 (joint 1 5.11x the plain fit), when
    # the simulated bodies were the DH table's parameters ±20 % read in the URDF's link frames (link 2's first
    # moment -6.3 kg m against the description's +1.2; links 2 and 3 not rigid bodies): the description's prior was
    # not 20 % off but wrong. With the true bodies the description's ±20 % (write_records), MSE / floor on joints
    # 1, 2: plain OLS 21 and 6936, identify (the consistent fit, prior weight 100) 3.6 and 3.0
    LoggedAs("PUMA 6 joints, training and validation over the lowest 35 % of the shoulder's range, the test over "
             "all of it, 10 s / 4 s / 6 s at 250 Hz, no dq",
             Lab("outside", puma(6), *(Log(seconds, 250.0, velocity=False) for seconds in (10.0, 4.0, 6.0)),
                 trained_range=(1, 0.35)), slow=True),
    # the same with a description far from the bodies (CAD without motors: masses halved, first moments at 35 %), the
    # prior the consistent candidate pulls toward along the directions the narrow range leaves open: identify 0.101x
    # the plain fit on joint 1, 0.007 in total; diagnose 0.098x, 0.009 (h-extrap)
    LoggedAs("the same, the URDF's inertials from CAD without motors (masses halved)",
             Lab("outside, wrong bodies", puma(6), *(Log(seconds, 250.0, velocity=False) for seconds in (10.0, 4.0, 6.0)),
                 trained_range=(1, 0.35), wrong_bodies=True), slow=True),
    LoggedAs("PUMA 6 joints, a logger's clock that did not tick on 0.5 % of the rows (two rows at the same t, each its "
             "own sample), 10 s / 4 s / 6 s at 250 Hz, no dq",
             Lab("stamps", puma(6), *(Log(seconds, 250.0, velocity=False) for seconds in (10.0, 4.0, 6.0))),
             clock_not_ticking, slow=True),
)


@pytest.mark.parametrize("case", [pytest.param(case, id=case.name, marks=marks(case)) for case in CELLS])
def test_the_defaults_run_and_predict_a_cells_log_as_well_as_a_plain_fit(case, tmp_path):
    outcome = run_logged(case, tmp_path)
    print(f"\nreproduced validation error (relative): {outcome['reproduced']}")
    as_well_as_the_plain_fit(case.name, outcome, f"chosen {outcome['selections']}; ")
    for label, error in outcome["reproduced"].items():
        assert error <= RELATIVE, (label, error)


def test_a_hold_is_cut_out_of_the_training_record_and_said(tmp_path):
    """Every joint's position unchanged for longer than ``max_gap`` (50 ms): a hold, cut out of the training record
    (the segment split there) with a :class:`HoldWarning`, its velocity and acceleration zero where a record is
    derived; runs of repeated positions shorter than that (a slow
    joint's quantised encoder, the TX40's 7.6 ms at 5 kHz) and a hold of one joint alone are not holds; with
    ``--min-speed`` the user's rule applies instead."""
    from dynamics.measurements import Measurements
    from estimation.data import HoldWarning
    from estimation.data.rest import holds, without_holds
    from estimation.identification.prepared import RecordedFile, training_without_holds

    t = np.arange(0.0, 2.0, 0.004)
    q = np.column_stack([np.sin(t), np.cos(2 * t)])
    q[100:150] = q[100]  # 0.196 s held: a hold (rows 100..149)
    q[300:310] = q[300]  # 36 ms: not one
    q[400:480, 0] = q[400, 0]  # one joint still, the other moving: not one
    assert holds(t, q, 0.05) == [(100, 150)]
    segment = Measurements(t, q, None, None, np.zeros_like(q), None, {})
    parts, dropped = without_holds(segment, 0.05)
    assert [part.n_samples for part in parts] == [100, 350] and dropped == 50
    assert parts[1].t[0] == t[150]
    with pytest.warns(HoldWarning, match="held still .* on 50 of 500 rows"):
        (file,) = training_without_holds([RecordedFile(tmp_path / "train.csv", (segment,))], 0.05)
    assert len(file.segments) == 2
    assert holds(t, q, 0.2) == []
    from estimation.preprocessing.differentiation import ButterworthDifferentiation

    derived = ButterworthDifferentiation(cutoff_hz=10.0).apply(segment)  # a hold's derivatives: zero, not the filter's
    assert np.all(derived.dq[100:150] == 0.0) and np.all(derived.ddq[100:150] == 0.0)
    assert np.all(derived.dq[300:310] != 0.0) and np.all(derived.dq[400:480, 1] != 0.0)



def test_a_joint_state_table_is_matched_to_the_robot_by_its_names(tmp_path):
    """``rostopic echo -p``'s table read through a column map: each index's joint taken from ``field.name<k>`` (at
    35f0061 index k was joint k + 1: the UR case above predicted 1322x worse than the plain fit, both verbs running),
    a joint of the log the robot lacks left out; a robot's joint no index names, or names changing between rows,
    refused naming them."""
    from estimation.data import MissingColumnError
    from estimation.data.log_formats import LogSource, joint_state_echo, parse_column_map, read_log_frame

    t = np.arange(0.0, 0.1, 0.01)
    frame = pd.DataFrame({f"q{j + 1}": (j + 1) * np.ones_like(t) for j in range(6)} | {"t": t}
                         | {f"tau{j + 1}": -(j + 1) * np.ones_like(t) for j in range(6)})
    table = rostopic_echo(frame, "train")
    table["field.name6"], table["field.position6"], table["field.effort6"] = "gripper_joint", 7.0, -7.0
    table.to_csv(tmp_path / "echo.csv", index=False)
    columns = parse_column_map("t=1e-9*field.header.stamp,q=field.position,tau=field.effort")
    read = read_log_frame(LogSource(tmp_path / "echo.csv", columns=columns), joint_names=UR_NAMES)
    assert joint_state_echo(table) == {"t": "1e-9*field.header.stamp", "q": "field.position", "tau": "field.effort"}
    assert joint_state_echo(frame) is None
    assert joint_state_echo(table.assign(**{"field.header.stamp": 0}))["t"] == "1e-9*%time"
    for j in range(6):
        assert np.all(read[f"q{j + 1}"] == j + 1) and np.all(read[f"tau{j + 1}"] == -(j + 1)), j
    assert "q7" not in read.columns
    with pytest.raises(MissingColumnError, match="joint\\(s\\) tool_joint are not among"):
        read_log_frame(LogSource(tmp_path / "echo.csv", columns=columns), joint_names=(*UR_NAMES, "tool_joint"))
    table.loc[3, "field.name0"] = "shoulder_pan_joint"
    table.to_csv(tmp_path / "changing.csv", index=False)
    with pytest.raises(MissingColumnError, match="field.name0 change from row to row"):
        read_log_frame(LogSource(tmp_path / "changing.csv", columns=columns), joint_names=UR_NAMES)


def test_joint_columns_named_by_the_robots_joints_are_read_by_name(tmp_path):
    """``<joint>_effort`` (and ``_position``, ``_velocity``; or ``effort.<joint>``...) read as ``tau<j>`` in the
    robot's order, said in a :class:`JointNamedColumnsWarning` that gives the map; a group is mapped only when every
    joint has exactly one such column, and a table with numbered columns is read as before."""
    from estimation.data.log_formats import JointNamedColumnsWarning, joint_named_columns
    from estimation.data.records import read_record
    from dynamics.models import build_model

    t = np.arange(0.0, 1.0, 0.01)
    frame = pd.DataFrame({f"q{j + 1}": (j + 1) * np.sin(t) for j in range(6)} | {"t": t}
                         | {f"tau{j + 1}": -(j + 1) * np.ones_like(t) for j in range(6)})
    table = named_by_joint(frame, "train")
    assert joint_named_columns(table, UR_NAMES) == {
        **{f"q{j + 1}": f"{UR_NAMES[j]}_position" for j in range(6)},
        **{f"tau{j + 1}": f"{UR_NAMES[j]}_effort" for j in range(6)}}
    assert joint_named_columns(frame, UR_NAMES) is None
    assert joint_named_columns(table, None) is None
    assert joint_named_columns(table.rename(columns={"elbow_joint_effort": "Effort.elbow_joint"}), UR_NAMES)[
        "tau3"] == "Effort.elbow_joint"
    ambiguous = table.assign(elbow_joint_torque=0.0)  # two torque columns for one joint: nothing guessed
    assert "tau1" not in joint_named_columns(ambiguous, UR_NAMES)
    assert "tau1" not in joint_named_columns(table.drop(columns="wrist_3_joint_effort"), UR_NAMES)
    table.to_csv(tmp_path / "named.csv", index=False)
    robot = load_robot(urdf=_written(tmp_path, ur_names(__import__("dynamics.urdf_export", fromlist=["robot_urdf"])
                                                        .robot_urdf(ur10e()))))
    model = build_model(robot, "internal")
    with pytest.warns(JointNamedColumnsWarning, match="tau3=elbow_joint_effort"):
        (segment,) = read_record(tmp_path / "named.csv", model=model, require=("tau",))
    for j in range(6):
        assert np.allclose(segment.q[:, j], (j + 1) * np.sin(t)) and np.all(segment.tau[:, j] == -(j + 1)), j


def _written(folder: Path, text: str) -> Path:
    path = folder / "robot.urdf"
    path.write_text(text)
    return path


def spreadsheet_export(files: dict) -> None:
    """Each file rewritten as a European spreadsheet exports it: ``;`` between the columns, ``,`` the decimal mark."""
    for path in files.values():
        pd.read_csv(path).to_csv(path, sep=";", decimal=",", index=False, float_format="%.17g")


def units_row(files: dict) -> None:
    """Each file with a units row beneath its header, the format's SI units as a lab writes them."""
    for path in files.values():
        lines = path.read_text().splitlines()
        units = {"t": "[s]", "q": "[rad]", "dq": "[rad/s]", "tau": "[N·m]"}
        lines.insert(1, ",".join(units[name.rstrip("0123456789")] for name in lines[0].split(",")))
        path.write_text("\n".join(lines) + "\n")


@pytest.mark.slow
@pytest.mark.parametrize("export, written", [(spreadsheet_export, "`;` separators and `,` decimals"),
                                             (units_row, "a units row beneath the names ([s], [rad], [N·m])")],
                         ids=["semicolons", "units row"])
def test_the_defaults_read_a_spreadsheets_export_and_a_units_row(export, written, tmp_path):
    """At 7f2677d every verb refused such files (naming the separator, or the text beneath the names); now they are
    read so, said in a :class:`DelimiterWarning` or :class:`UnitsRowWarning`, and predicted as the plain
    comma-separated file is (against the plain fit)."""
    from benchmarks.bench_real_robots import PlainFit
    from tests.test_unseen_robot_labs import verbs_against_the_plain_fit, write_records

    case = Lab(f"PUMA 3 joints, {written}, 8 s / 3 s / 5 s at 250 Hz, no dq", puma(3),
               *(Log(seconds, 250.0, velocity=False) for seconds in (8.0, 3.0, 5.0)))
    urdf, records, files, spread = write_records(case, tmp_path)
    export(files)
    assert not files["train"].read_text().splitlines()[1].startswith("0,") or ";" in files["train"].read_text()
    plain = PlainFit(["--urdf", str(urdf)])
    cutoff, theta = plain.fit(records["train"], records["validate"], rate_hz=250.0)
    predicted_plain, kept = plain.predict(records["test"], cutoff, theta)
    outcome = verbs_against_the_plain_fit(urdf, files, records["test"], kept, predicted_plain, tmp_path)
    outcome = {**outcome, "cutoff": cutoff, "floor": (0.02 * spread) ** 2}
    print(f"\nreproduced validation error (relative): {outcome['reproduced']}")
    as_well_as_the_plain_fit(case.name, outcome, f"chosen {outcome['selections']}; ")
    for label, error in outcome["reproduced"].items():
        assert error <= RELATIVE, (label, error)


def test_a_csv_dialect_is_read_where_header_and_rows_agree(tmp_path):
    """``;`` with ``,`` decimals, a tab with ``.`` decimals: read so, said; a row that does not split as the header,
    or a value with two commas (thousands) or both marks: nothing guessed (the message naming the separator as before)."""
    from estimation.data import DelimiterWarning, MeasurementError
    from estimation.data.loading import csv_dialect
    from estimation.data.records import read_record

    assert csv_dialect("t;q1;tau1\n", ["0;0;1\n", "0,004;1,5;-2\n"]) == (";", ",")
    assert csv_dialect("t\tq1\ttau1\n", ["0.004\t1.5\t-2\n", ""]) == ("\t", ".")
    assert csv_dialect("t,q1,tau1\n", ["0.004,1.5,-2\n"]) is None
    assert csv_dialect("t;q1;tau1\n", ["0;0;1\n", "0,004;1,5\n"]) is None
    assert csv_dialect("t;q1;tau1\n", ["0,004;1.500,5;2\n"]) is None
    assert csv_dialect("t;q1;tau1\n", ["0,004;1,500,5;2\n"]) is None
    t = np.arange(0.0, 1.0, 0.01)
    frame = pd.DataFrame({"t": t, "q1": np.sin(t), "tau1": np.cos(t)})
    frame.to_csv(tmp_path / "semicolon.csv", sep=";", decimal=",", index=False, float_format="%.17g")
    with pytest.warns(DelimiterWarning, match="separated by ';', ',' the decimal mark"):
        (segment,) = read_record(tmp_path / "semicolon.csv", require=("tau",))
    assert np.array_equal(segment.q[:, 0], frame["q1"].to_numpy()) and np.array_equal(segment.tau[:, 0], np.cos(t))
    from dynamics.models import build_model
    from estimation.streaming.chunks import read_chunks

    model = build_model(load_robot("puma560", joints=1), "internal")
    with pytest.warns(DelimiterWarning):
        chunks = list(read_chunks(tmp_path / "semicolon.csv", model, chunk_size=30))
    assert np.array_equal(np.concatenate([chunk.tau[:, 0] for chunk in chunks]), np.cos(t))  # streamed alike
    (tmp_path / "uneven.csv").write_text("t;q1;tau1\n0,0;1,0\n0,1;1,1;2,0\n")
    with pytest.raises(MeasurementError, match="separated by ';'"):
        read_record(tmp_path / "uneven.csv", require=("tau",))


def test_a_units_row_of_si_units_is_skipped_and_said(tmp_path):
    """``[s], [rad], [N m]`` beneath the names: skipped (in memory and streamed) with a :class:`UnitsRowWarning`;
    a row naming another unit of an angle (``deg``) is skipped and the angle converted; one naming a unit of
    another quantity (``mA`` for a torque) or holding a number is not skipped (the text refused as before)."""
    from dynamics.models import build_model
    from estimation.data import DelimiterWarning, NonFiniteError, UnitsRowWarning
    from estimation.data.loading import si_units_row
    from estimation.data.records import read_record
    from estimation.streaming.chunks import read_chunks

    names = ["t", "q1", "q2", "dq1", "tau1", "tau2", "note"]
    assert si_units_row(names, ["s", "[rad]", "(m)", "rad/s", "N·m", "N", "free text"])
    assert si_units_row(names, ["sec", "rad", "m", "[rad/s]", "Nm", "N.m", ""])
    assert not si_units_row(names, ["s", "deg", "m", "rad/s", "Nm", "N", ""])
    assert not si_units_row(names, ["s", "rad", "m", "rad/s", "mNm", "N", ""])
    assert not si_units_row(names, ["0", "rad", "m", "rad/s", "Nm", "N", ""])
    assert not si_units_row(names, ["s", "rad"])
    t = np.arange(0.0, 1.0, 0.01)
    frame = pd.DataFrame({"t": t, "q1": np.sin(t), "tau1": np.cos(t)})
    files = {"a": tmp_path / "units.csv"}
    frame.to_csv(files["a"], index=False, float_format="%.17g")
    units_row(files)
    with pytest.warns(UnitsRowWarning, match=r"\[s\],\[rad\],\[N·m\]"):
        (segment,) = read_record(files["a"], require=("tau",))
    assert np.array_equal(segment.tau[:, 0], np.cos(t))
    model = build_model(load_robot("puma560", joints=1), "internal")
    with pytest.warns(UnitsRowWarning):
        chunks = list(read_chunks(files["a"], model, chunk_size=30))
    assert np.array_equal(np.concatenate([chunk.tau[:, 0] for chunk in chunks]), np.cos(t))
    spreadsheet = {"b": tmp_path / "both.csv"}
    spreadsheet["b"].write_text(files["a"].read_text())
    spreadsheet_export(spreadsheet)  # ';' between the columns (the numbers read as text: '.' kept)
    with pytest.warns((UnitsRowWarning, DelimiterWarning)) as said:
        (segment,) = read_record(spreadsheet["b"], require=("tau",))
    assert {type(item.message) for item in said} == {UnitsRowWarning, DelimiterWarning}
    assert np.array_equal(segment.tau[:, 0], np.cos(t))
    text = files["a"].read_text().replace("[rad]", "[deg]")  # another unit of an angle: converted (h-unseen12)
    (tmp_path / "degrees.csv").write_text(text)
    with pytest.warns(UnitsRowWarning, match="q1 read as SI units"):
        (segment,) = read_record(tmp_path / "degrees.csv", require=("tau",))
    assert np.allclose(segment.q[:, 0], np.radians(np.sin(t)), rtol=1e-15, atol=0.0)
    text = files["a"].read_text().replace("[N·m]", "[mA]")  # a current: its factor is the robot's, refused
    (tmp_path / "current.csv").write_text(text)
    with pytest.raises(NonFiniteError, match="units"):
        read_record(tmp_path / "current.csv", require=("tau",))


def test_a_time_column_under_another_name_is_read_where_its_unit_is_plain():
    """``time``, ``Timestamp``, ``time [s]`` in seconds, ``time_ms``, ``stamp_ns`` scaled; a name without a unit
    whose steps are not seconds (ns since 1970), two time columns, or a ``t`` column: nothing guessed."""
    from estimation.data.log_formats import time_column

    t = np.arange(0.0, 1.0, 0.004)
    frame = pd.DataFrame({"q1": np.sin(t)})
    assert time_column(frame.assign(time=t)) == "time"
    assert time_column(frame.assign(Timestamp=t)) == "Timestamp"
    assert time_column(frame.assign(**{"time [s]": t})) == "time [s]"
    assert time_column(frame.assign(time_ms=1e3 * t)) == "0.001*time_ms"
    assert time_column(frame.assign(stamp_ns=np.round(1e9 * t).astype(np.int64) + EPOCH_NS)) == "1e-09*stamp_ns"
    assert time_column(frame.assign(time=np.round(1e9 * t).astype(np.int64) + EPOCH_NS)) is None
    assert time_column(frame.assign(time=1e3 * t)) is None  # ms without a unit in the name: not seconds' steps
    assert time_column(frame.assign(time=t, timestamp=t)) is None
    assert time_column(frame.assign(t=t, time=t)) is None
    assert time_column(frame.assign(runtime=t)) is None
