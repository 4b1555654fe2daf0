"""Logs as robot vendors' controllers and drivers write them, read without a column map
(:mod:`estimation.data.vendor_logs`).

Each format is written from its documented names: Universal Robots' RTDE recorder (``timestamp``, ``actual_q_0..5``,
``actual_qd_0..5``, ``target_qdd_0..5``, ``actual_current_0..5``, ``target_moment_0..5``, ``joint_temperatures_0..5``,
``actual_TCP_speed_0..5``), libfranka's robot-state log (``q[0]..q[6]``, ``q_d``, ``dq``, ``theta``, ``tau_J``,
``tau_J_d``, ``dtau_J``, ``tau_ext_hat_filtered``, ``O_T_EE[0..15]``, ``elbow[0..1]``, separated by ``", "``), a
ROS 2 ``LBRState`` of KUKA's FRI exported with its arrays in cells (``measured_joint_position``,
``commanded_joint_position``, ``ipo_joint_position``, ``measured_torque``, ``commanded_torque``,
``external_torque``), old FRI's ``msrJntPos1..7`` / ``cmdJntPos`` / ``msrJntTrq`` / ``estExtJntTrq``, a KUKA trace's
``AxisActPos_A1 [deg]``, a Kinova Kortex feedback export (``actuators[0].position``, ``.torque``,
``.current_motor``, ``.temperature_motor``), a ROS 2 ``JointState`` export (``name[k]`` beside ``position[k]``, the
publisher's order, a gripper's fingers), a PlotJuggler export (``/joint_states/<joint>/effort``). The cheap tests
read each table; the slow ones run the default ``oed identify`` and ``oed diagnose``, then ``oed predict`` on a
record no choice saw, against the plain least-squares fit (:mod:`tests.test_unseen_robot_labs`)."""

from __future__ import annotations

import json
import shlex
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from estimation.data.loading import MissingColumnError
from estimation.data.vendor_logs import AmbiguousColumnsError, array_cells, joint_groups, vendor_columns

UR = [f"{name}_joint" for name in ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")]
PANDA = [f"panda_joint{j}" for j in range(1, 8)]
#: a UR's current to joint torque, N·m/A (the motor's constant times the gear ratio), for the tests' logs
CURRENT_TO_TORQUE = (13.0, 13.0, 10.0, 4.0, 4.0, 4.0)
#: RTDE's ``timestamp``: seconds since the controller started
RTDE_START = 1834.5


def signals(n: int, rows: int = 50) -> dict[str, np.ndarray]:
    """Distinct values for each joint's quantities: ``q``, ``dq``, ``tau`` of joint ``j`` (1-based) tell it apart;
    each torque does positive work on its joint's motion (as a drive's)."""
    t = np.arange(rows) * 0.002
    return {"t": t, **{f"q{j}": 0.1 * j * np.sin(t + j) for j in range(1, n + 1)},
            **{f"dq{j}": 0.1 * j * np.cos(t + j) for j in range(1, n + 1)},
            **{f"tau{j}": 5.0 * j * np.cos(t + j) + 0.01 * j for j in range(1, n + 1)}}  # pushing the motion


def rtde(values: dict[str, np.ndarray], n: int = 6) -> pd.DataFrame:
    """What UR's RTDE recorder (``record.py``) writes for the usual recipe: one column a vector element, from 0."""
    table = {"timestamp": RTDE_START + values["t"]}
    for name, source, change in (("target_q", "q", 0.01), ("actual_q", "q", 0.0), ("target_qd", "dq", 0.0),
                                 ("actual_qd", "dq", 0.0), ("target_qdd", "dq", 0.0)):
        table.update({f"{name}_{j}": values[f"{source}{j + 1}"] + change for j in range(n)})
    table.update({f"target_current_{j}": values[f"tau{j + 1}"] / CURRENT_TO_TORQUE[j] * 1.02 for j in range(n)})
    table.update({f"actual_current_{j}": values[f"tau{j + 1}"] / CURRENT_TO_TORQUE[j] for j in range(n)})
    table.update({f"target_moment_{j}": values[f"tau{j + 1}"] * 1.05 for j in range(n)})
    table.update({f"joint_temperatures_{j}": np.full_like(values["t"], 31.0 + j) for j in range(n)})
    table.update({f"actual_TCP_speed_{j}": 0.01 * values["dq1"] for j in range(n)})
    table.update({"actual_TCP_pose_0": values["q1"], "speed_scaling": np.ones_like(values["t"]),
                  "actual_execution_time": np.full_like(values["t"], 0.3)})
    table.update({f"joint_mode_{j}": np.full(values["t"].shape, 253) for j in range(n)})
    return pd.DataFrame(table)


def libfranka(values: dict[str, np.ndarray], n: int = 7) -> pd.DataFrame:
    """A libfranka robot-state log (``franka::RobotState`` fields, arrays as ``name[k]``, ``", "`` between columns
    as its CSV writer puts them, read here as names with a leading space)."""
    table = {"time": values["t"]}
    def array(name, columns):
        table.update({f" {name}[{k}]": column for k, column in enumerate(columns)})
    array("O_T_EE", [values["q1"]] * 16)
    array("elbow", [values["q3"], values["q1"]])
    array("tau_J", [values[f"tau{j}"] for j in range(1, n + 1)])
    array("tau_J_d", [values[f"tau{j}"] * 0.97 for j in range(1, n + 1)])
    array("dtau_J", [values[f"dq{j}"] for j in range(1, n + 1)])
    array("q", [values[f"q{j}"] for j in range(1, n + 1)])
    array("q_d", [values[f"q{j}"] + 0.001 for j in range(1, n + 1)])
    array("dq", [values[f"dq{j}"] for j in range(1, n + 1)])
    array("dq_d", [values[f"dq{j}"] for j in range(1, n + 1)])
    array("ddq_d", [values[f"dq{j}"] for j in range(1, n + 1)])
    array("theta", [values[f"q{j}"] * 1.0001 for j in range(1, n + 1)])
    array("dtheta", [values[f"dq{j}"] for j in range(1, n + 1)])
    array("tau_ext_hat_filtered", [0.1 * values[f"tau{j}"] for j in range(1, n + 1)])
    return pd.DataFrame(table)


def in_cells(columns: list[np.ndarray]) -> list[str]:
    """The rows of ``columns`` as a ROS 2 message's array printed in a cell: ``"[0.1, 0.2, ...]"``."""
    return ["[" + ", ".join(f"{value:.10g}" for value in row) + "]" for row in np.column_stack(columns)]


def lbr_state(values: dict[str, np.ndarray], n: int = 7) -> pd.DataFrame:
    """KUKA FRI's ``LBRState`` (lbr_fri_ros2) exported from a bag, one cell an array."""
    joints = range(1, n + 1)
    return pd.DataFrame({
        "timestamp": values["t"], "sample_time": np.full_like(values["t"], 0.002),
        "measured_joint_position": in_cells([values[f"q{j}"] for j in joints]),
        "commanded_joint_position": in_cells([values[f"q{j}"] + 0.002 for j in joints]),
        "ipo_joint_position": in_cells([values[f"q{j}"] + 0.001 for j in joints]),
        "measured_torque": in_cells([values[f"tau{j}"] for j in joints]),
        "commanded_torque": in_cells([values[f"tau{j}"] * 0.0 for j in joints]),
        "external_torque": in_cells([values[f"tau{j}"] * 0.05 for j in joints]),
        "tracking_performance": np.ones_like(values["t"])})


def read(frame: pd.DataFrame, names, n: int, torque: bool = True):
    return vendor_columns(array_cells(frame), names, n, "log.csv", torque=torque)


def test_ur_rtde_reads_actual_positions_velocities_and_currents_as_currents():
    """RTDE: ``actual_q``/``actual_qd`` read, numbered from 0; no joint torque is measured, so the actual currents
    are read as the motor currents ``im`` (the transmission's torque constants turn them into torques), never
    ``target_moment`` (the controller's command); the message names what was left aside."""
    reading = read(rtde(signals(6)), UR, 6)
    assert {key: value for key, value in reading.columns.items() if not key.startswith("im")} == {
        "q": "actual_q_", "dq": "actual_qd_"}
    assert [reading.columns[f"im{j}"] for j in range(1, 7)] == [f"actual_current_{j}" for j in range(6)]
    for said in ("target_moment_0..target_moment_5 (commanded torques)", "target_q_0..target_q_5 (commanded "
                 "positions)", "joint_temperatures_0..joint_temperatures_5 (no joint", "actual_TCP_speed_0",
                 "target_current_0..target_current_5 (commanded currents)", "--transmission"):
        assert said in reading.message, (said, reading.message)


def test_libfranka_reads_q_dq_and_the_measured_joint_torque_only():
    """libfranka: ``q[k]``, ``dq[k]``, ``tau_J[k]``; ``tau_J_d`` (desired), ``tau_ext_hat_filtered`` (external),
    ``theta`` (the motors') and the 16 entries of a pose left aside."""
    values = signals(7)
    reading = read(libfranka(values), PANDA, 7)
    assert reading.columns == {**{f"q{j}": f" q[{j - 1}]" for j in range(1, 8)},
                               **{f"dq{j}": f" dq[{j - 1}]" for j in range(1, 8)},
                               **{f"tau{j}": f" tau_J[{j - 1}]" for j in range(1, 8)}}
    for said in ("tau_J_d[0].. tau_J_d[6] (commanded torques)", "tau_ext_hat_filtered[6] (external torques)",
                 "theta[6] (no joint"):
        assert said in reading.message, (said, reading.message)


def test_kuka_fri_arrays_in_cells_read_the_measured_torque():
    """FRI's ``LBRState`` with arrays in cells: ``measured_joint_position`` and ``measured_torque`` read; the
    commanded, interpolated and external ones left aside."""
    values = signals(7)
    frame = array_cells(lbr_state(values))
    assert np.allclose(frame["measured_torque[3]"], values["tau4"], rtol=1e-9)
    reading = vendor_columns(frame, [f"lbr_A{j}" for j in range(1, 8)], 7, "lbr.csv")
    assert reading.columns["q4"] == "measured_joint_position[3]" and reading.columns["tau7"] == "measured_torque[6]"
    assert "dq1" not in reading.columns
    for said in ("commanded_joint_position[0]..commanded_joint_position[6] (commanded positions)",
                 "ipo_joint_position[0]", "external_torque[0]..external_torque[6] (external torques)"):
        assert said in reading.message, (said, reading.message)


def test_old_fri_kuka_trace_and_kortex_names():
    """Old FRI (``msrJntPos1..7``, 1-based, camelCase), a KUKA trace (axes ``A1..A6``, degrees in the name: turned
    into radians) and a Kinova Kortex export (``actuators[k].torque`` beside ``current_motor``: the torque read)."""
    values = signals(7)
    fri = pd.DataFrame({"time": values["t"]} | {f"{name}{j}": values[f"{source}{j}"] for name, source in (
        ("msrJntPos", "q"), ("cmdJntPos", "q"), ("msrJntTrq", "tau"), ("estExtJntTrq", "tau")) for j in range(1, 8)})
    reading = read(fri, None, 7)
    assert reading.columns == {"q": "msrJntPos", "tau": "msrJntTrq"}, reading.columns
    trace = pd.DataFrame({"Time [ms]": 1e3 * values["t"]} | {f"{name}_A{j} [{unit}]": np.degrees(values[f"q{j}"])
                          for name, unit in (("AxisActPos", "deg"), ("AxisCmdPos", "deg")) for j in range(1, 7)}
                         | {f"AxisActTorque_A{j} [Nm]": values[f"tau{j}"] for j in range(1, 7)})
    reading = read(trace, None, 6)
    factor = float(np.pi / 180.0)
    assert reading.columns["q1"] == f"{factor!r}*AxisActPos_A1 [deg]" and reading.columns["tau6"] == \
        "AxisActTorque_A6 [Nm]", reading.columns
    kortex = pd.DataFrame({"time": values["t"]} | {f"actuators[{k}].{name}": values[f"{source}{k + 1}"] * scale
                           for name, source, scale in (("position", "q", 1.0), ("velocity", "dq", 1.0),
                                                       ("torque", "tau", 1.0), ("current_motor", "tau", 0.1),
                                                       ("temperature_motor", "q", 0.0)) for k in range(7)})
    reading = read(kortex, None, 7)
    assert reading.columns["tau3"] == "actuators[2].torque" and reading.columns["dq7"] == "actuators[6].velocity"
    assert "the currents: a measured joint torque is read rather than a current" in reading.message


def test_a_joint_state_export_is_matched_by_its_names_and_plotjuggler_by_the_robots():
    """A ROS 2 ``JointState`` export (``name[k]`` in the publisher's order, two gripper fingers beside the arm's
    joints) is matched to the robot's joints by the names logged; a PlotJuggler export by the robot's names in
    the columns (``/joint_states/panda_joint3/effort``)."""
    values = signals(7)
    order = [2, 0, 1, 7, 3, 4, 5, 6, 8]  # the publisher's order: panda_joint3 first, the fingers among them
    names = PANDA + ["panda_finger_joint1", "panda_finger_joint2"]
    logged = [names[index] for index in order]
    def of(source, index):
        return values[f"{source}{index + 1}"] if index < 7 else np.zeros_like(values["t"])
    table = pd.DataFrame({"header.stamp.sec": np.zeros(len(values["t"])), "time": values["t"]}
                         | {f"name[{k}]": [name] * len(values["t"]) for k, name in enumerate(logged)}
                         | {f"{field}[{k}]": of(source, index) for field, source in (("position", "q"),
                            ("velocity", "dq"), ("effort", "tau")) for k, index in enumerate(order)})
    reading = read(table, PANDA, 7)
    assert reading.columns["q1"] == "position[1]" and reading.columns["tau3"] == "effort[0]"
    assert reading.columns["dq4"] == "velocity[4]", reading.columns
    plot = pd.DataFrame({"__time": values["t"]} | {f"/joint_states/{name}/{field}": values[f"{source}{j}"]
                        for field, source in (("position", "q"), ("effort", "tau"))
                        for j, name in enumerate(PANDA, start=1)})
    reading = read(plot, PANDA, 7)
    assert reading.columns["tau5"] == "/joint_states/panda_joint5/effort" and "dq1" not in reading.columns


def test_two_measured_torques_are_an_error_naming_both_and_the_maps():
    """``effort_k`` and ``torque_k`` beside each other: no rule chooses: the error names both and a map for each."""
    values = signals(6)
    table = pd.DataFrame({"t": values["t"]} | {f"position_{j}": values[f"q{j + 1}"] for j in range(6)}
                         | {f"effort_{j}": values[f"tau{j + 1}"] for j in range(6)}
                         | {f"torque_{j}": values[f"tau{j + 1}"] for j in range(6)})
    with pytest.raises(AmbiguousColumnsError, match=r"effort_0..effort_5 and torque_0..torque_5 could each be the "
                       r"measured joint torques.*--columns q=position_,tau=effort_ or "
                       r"--columns q=position_,tau=torque_"):
        read(table, UR, 6)


def test_a_commanded_torque_alone_is_refused_naming_the_map_that_reads_it():
    """Only ``target_moment`` (the command) beside the positions: the torques are needed, so the reader refuses
    it as the measured torque and names the map; without a torque model the positions are read."""
    frame = rtde(signals(6)).drop(columns=[f"{name}_{j}" for name in ("actual_current", "target_current")
                                           for j in range(6)])
    with pytest.raises(MissingColumnError, match=r"no measured joint torque: the torques logged are "
                       r"target_moment_0..target_moment_5 \(commanded\).*"
                       r"--columns q=actual_q_,dq=actual_qd_,tau=target_moment_$"):
        read(frame, UR, 6)
    assert read(frame, UR, 6, torque=False).columns == {"q": "actual_q_", "dq": "actual_qd_"}


def test_groups_need_every_joint_and_numbers_in_the_format_are_left_alone():
    """A group whose indices are not the robot's joints (a pose's 16 entries, 5 of 6 joints) is not one; a table
    with ``q1..`` is not read by the rule."""
    values = signals(6)
    groups = joint_groups(rtde(values).drop(columns="actual_q_5"), UR, 6)
    assert not [group for group in groups if group.pattern == "actual_q_{}"]
    assert vendor_columns(pd.DataFrame(values), UR, 6, "plain.csv") is None


def test_ur_rtde_currents_through_the_transmission_give_the_joint_torques(tmp_path):
    """The reader end to end: a UR RTDE file (time from ``timestamp``), read with a transmission holding the
    torque constants: ``tau`` is the current times the constant, ``q`` and ``dq`` the actual ones; without the
    transmission the currents are refused naming the option."""
    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from dynamics.transmission import TransmissionError
    from dynamics.transmission_files import transmission_from_json
    from estimation.data.log_formats import LogSource, parse_column_map
    from estimation.data.motor_side import read_record_with_transmission
    from estimation.data.vendor_logs import VendorColumnsWarning

    values = signals(6, rows=400)
    rtde(values).to_csv(tmp_path / "ur.csv", index=False, float_format="%.12g")
    model = build_model(load_robot("puma560"), "internal")
    transmission = transmission_from_json({"ratios": [1.0] * 6, "torque_constants": list(CURRENT_TO_TORQUE)},
                                          model.robot)
    with warnings.catch_warnings(record=True) as said_warnings:
        warnings.simplefilter("always")
        (segment,) = read_record_with_transmission(tmp_path / "ur.csv", model=model, transmission=transmission)
    assert any("im from actual_current_0..actual_current_5" in str(item.message) for item in said_warnings)
    recorded = segment.as_recorded if segment.as_recorded is not None else segment
    expected = np.column_stack([values[f"tau{j}"] for j in range(1, 7)])
    assert np.allclose(recorded.tau, expected, rtol=1e-9, atol=1e-9)
    assert np.allclose(recorded.q, np.column_stack([values[f"q{j}"] for j in range(1, 7)]), atol=1e-11)
    said = str(caught[0].message) if (caught := [item for item in said_warnings if item.category is
                                                  VendorColumnsWarning]) else ""
    columns = shlex.split(said[said.rindex("(--columns ") + len("(--columns "):-1])[0]
    assert columns.startswith("t=timestamp,q=actual_q_,dq=actual_qd_,im1=actual_current_0,"), columns
    with warnings.catch_warnings():  # the map the warning gives reads the file alike
        warnings.simplefilter("ignore")
        (mapped,) = read_record_with_transmission(LogSource(tmp_path / "ur.csv", columns=parse_column_map(columns)),
                                                  model=model, transmission=transmission)
    assert np.array_equal(mapped.tau, segment.tau) and np.array_equal(mapped.q, segment.q)
    with pytest.raises(TransmissionError, match="need the transmission: --transmission"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        read_record_with_transmission(tmp_path / "ur.csv", model=model, transmission=None)


#: a ROS 2 or EGM clock's seconds since 1970 at the start of a test's log, with a part of a second: the joined time
#: is counted from the first row's whole second (``STAMP_START - floor(STAMP_START)`` at the first row)
STAMP_START = 1764300000.25


def split_seconds(t: np.ndarray, per_second: float) -> tuple[np.ndarray, np.ndarray]:
    """``t`` (s from the log's start) as a clock's whole seconds since 1970 and the fraction in ``1/per_second``
    (1e9: ROS 2's ``nanosec``; 1e6: EGM's ``usec``), integers as the messages hold them."""
    ticks = np.round((STAMP_START + t) * per_second).astype(np.int64)
    return ticks // int(per_second), ticks % int(per_second)


def abb_egm(values: dict[str, np.ndarray], n: int = 6, torques: bool = True) -> pd.DataFrame:
    """An ABB EGM ``EgmRobot`` stream flattened to a table (egm.proto: ``header``, ``feedBack`` and ``planned``
    with their ``joints`` in degrees and ``time`` an ``EgmClock`` of seconds and microseconds, the additional axes'
    ``externalJoints``, ``mciState``); EGM carries no torque: the lab's drive torques joined as ``tau1..``."""
    sec, usec = split_seconds(values["t"], 1e6)
    table = {"header.seqno": np.arange(len(values["t"])), "header.tm": np.round(1e3 * values["t"]).astype(int),
             "header.mtype": np.full(len(values["t"]), 2)}
    table |= {"feedBack.time.sec": sec, "feedBack.time.usec": usec}
    table |= {f"feedBack.joints.joints[{k}]": np.degrees(values[f"q{k + 1}"]) for k in range(n)}
    table |= {f"feedBack.externalJoints.joints[{k}]": 500.0 + 10.0 * values["t"] for k in range(6)}
    table |= {f"feedBack.cartesian.pos.{axis}": 800.0 + values["q1"] for axis in "xyz"}
    table |= {"planned.time.sec": sec, "planned.time.usec": usec}
    table |= {f"planned.joints.joints[{k}]": np.degrees(values[f"q{k + 1}"]) + 0.05 for k in range(n)}
    table |= {"mciState.state": np.full(len(values["t"]), 3), "utilizationRate": np.full(len(values["t"]), 12.5)}
    if torques:
        table |= {f"tau{j}": values[f"tau{j}"] for j in range(1, n + 1)}
    return pd.DataFrame(table)


def ros2_joint_state(values: dict[str, np.ndarray], names: list[str], n: int) -> pd.DataFrame:
    """A ROS 2 ``sensor_msgs/JointState`` topic exported to CSV with the message's fields as columns: the header's
    ``builtin_interfaces/Time`` split in ``header.stamp.sec`` and ``header.stamp.nanosec``, ``header.frame_id``, and
    ``name``, ``position``, ``velocity``, ``effort`` arrays in cells, the publisher's order (joint 2 first, a
    gripper's finger among them)."""
    sec, nanosec = split_seconds(values["t"], 1e9)
    order = [1, 0, n] + list(range(2, n))  # the finger (index n) third
    logged = [names[index] if index < n else "gripper_finger_joint" for index in order]
    def of(source, index):
        return values[f"{source}{index + 1}"] if index < n else np.full_like(values["t"], 0.01)
    return pd.DataFrame({"header.stamp.sec": sec, "header.stamp.nanosec": nanosec,
                         "header.frame_id": [""] * len(sec),
                         "name": ["[" + ", ".join(f"'{name}'" for name in logged) + "]"] * len(sec),
                         "position": in_cells([of("q", index) for index in order]),
                         "velocity": in_cells([of("dq", index) if "dq1" in values else np.zeros_like(values["t"])
                                               for index in order]),
                         "effort": in_cells([of("tau", index) for index in order])})


def read_file(frame: pd.DataFrame, path: Path, robot, columns: str | None = None):
    """The table written to ``path`` read by the in-memory reader for ``robot`` (a viscous internal model), with
    the warnings it gave; ``columns`` a ``--columns`` map to read it with instead."""
    from dynamics.models import build_model
    from estimation.data.log_formats import LogSource, parse_column_map
    from estimation.data.records import read_measurements

    frame.to_csv(path, index=False, float_format="%.12g")
    source = path if columns is None else LogSource(path, columns=parse_column_map(columns))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        read = read_measurements(source, model=build_model(robot, "internal", "viscous"))
    return read.as_recorded, [str(warning.message) for warning in caught]


def said_map(messages: list[str], kind: str) -> str:
    """The ``--columns`` map the reader's warning of ``kind`` gives (unquoted)."""
    said = next(message for message in messages if kind in message)
    return shlex.split(said[said.rindex("--columns"):].rstrip(")"))[1]


def test_abb_egm_reads_the_feedback_joints_in_degrees_and_its_clock(tmp_path):
    """EGM: ``feedBack.joints.joints[k]`` read as the joint angles, in degrees as the protocol sends them (said),
    the time joined from ``feedBack.time.sec`` and ``usec`` (``planned.time`` is the plan's); ``planned.joints``
    (the command) and ``externalJoints`` (the additional axes) left aside. The maps the warnings give read the same
    values. At 6ee74d4 the file was refused: no column t."""
    from dynamics.robots import load_robot

    values = signals(6, rows=200)
    robot = load_robot("puma560", joints=6)
    read, said = read_file(abb_egm(values), tmp_path / "egm.csv", robot)
    assert np.allclose(read.q, np.column_stack([values[f"q{j}"] for j in range(1, 7)]), atol=1e-12)
    assert np.allclose(read.t, values["t"] + 0.25, atol=1e-9) and np.allclose(read.tau[:, 2], values["tau3"])
    vendor = next(message for message in said if "controller's log" in message)
    for part in ("q from feedBack.joints.joints[0]..feedBack.joints.joints[5]", "degrees by its protocol",
                 "planned.joints.joints[0]..planned.joints.joints[5] (commanded positions)",
                 "feedBack.externalJoints.joints[0]"):
        assert part in vendor, (part, vendor)
    assert "tau1..tau6" not in vendor  # the format's own columns are read, not left aside
    assert any("feedBack.time.sec+1e-06*feedBack.time.usec" in message for message in said), said
    mapped, _ = read_file(abb_egm(values), tmp_path / "egm.csv", robot, columns=said_map(said, "controller's log"))
    assert np.array_equal(mapped.q, read.q) and np.array_equal(mapped.t, read.t)


def test_abb_egm_with_its_plan_alone_is_refused_naming_the_map(tmp_path):
    """An EGM table holding only ``planned.joints`` (the positions the controller planned, not those the joints
    reached) is refused as the measured motion, naming the map that would read it."""
    from dynamics.robots import load_robot

    table = abb_egm(signals(6, rows=100)).drop(columns=[f"feedBack.joints.joints[{k}]" for k in range(6)])
    with pytest.raises(MissingColumnError, match=r"no measured joint positions: the positions logged are "
                       r"planned.joints.joints\[0\]..planned.joints.joints\[5\] \(commanded\)"):
        read_file(table, tmp_path / "planned.csv", load_robot("puma560", joints=6))


def test_a_ros2_joint_state_export_with_its_stamp_split_is_read_by_its_names(tmp_path):
    """A ROS 2 ``JointState`` export: ``header.stamp.sec`` and ``header.stamp.nanosec`` joined into the time (to the
    nanosecond: counted from the first row's second), the arrays in cells matched to the robot's joints by the
    ``name`` cell (the publisher's order, a finger among them). At 6ee74d4: refused, no column t. The same stamp as
    bare ``sec`` and ``nanosec`` columns reads alike; two split stamps are an error naming a map for each."""
    from dynamics.robots import load_robot

    values = signals(6, rows=300)
    robot = load_robot("puma560", joints=6)
    table = ros2_joint_state(values, robot.joint_names, 6)
    read, said = read_file(table, tmp_path / "joint_states.csv", robot)
    assert np.allclose(read.t, values["t"] + 0.25, atol=1e-9)
    assert np.allclose(read.tau, np.column_stack([values[f"tau{j}"] for j in range(1, 7)]), rtol=1e-9)
    assert any("header.stamp.sec+1e-09*header.stamp.nanosec" in message for message in said), said
    bare, _ = read_file(table.rename(columns={"header.stamp.sec": "sec", "header.stamp.nanosec": "nanosec"}),
                        tmp_path / "bare.csv", robot)
    assert np.array_equal(bare.t, read.t)
    twice = table.assign(**{"receive.sec": table["header.stamp.sec"], "receive.nanosec": table["header.stamp.nanosec"]})
    with pytest.raises(AmbiguousColumnsError, match=r"could each be the time.*--columns "
                       r"'t=header.stamp.sec\+1e-09\*header.stamp.nanosec' or --columns "
                       r"'t=receive.sec\+1e-09\*receive.nanosec'"):
        read_file(twice, tmp_path / "twice.csv", robot)


#: a horizontal 3-joint arm (every joint about the vertical, damping 4 N m s/rad: the drives do work on average)
#: in MuJoCo's MJCF driven by servos: a ``<position>`` servo (kp, kv) with a gear, a ``<velocity>`` servo, a
#: ``<general>`` servo written with its gain and bias (a position servo's ``gainprm``/``biasprm``)
SERVO_ARM = """<mujoco model="servo_arm">
  <compiler angle="radian" autolimits="true"/>
  <option gravity="0 0 -9.81" timestep="0.002" integrator="implicitfast"/>
  <worldbody>
    <body name="link1" pos="0 0 0.3">
      <inertial pos="0 0 0.1" mass="3" diaginertia="0.03 0.03 0.01"/>
      <joint name="j1" type="hinge" axis="0 0 1" damping="4"/>
      <body name="link2" pos="0 0 0.2">
        <inertial pos="0.15 0 0" mass="2" diaginertia="0.004 0.02 0.02"/>
        <joint name="j2" type="hinge" axis="0 0 1" damping="4"/>
        <body name="link3" pos="0.3 0 0">
          <inertial pos="0.12 0 0" mass="1.2" diaginertia="0.002 0.01 0.01"/>
          <joint name="j3" type="hinge" axis="0 0 1" damping="4"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position name="a1" joint="j1" kp="400" kv="20" gear="2"/>
    <velocity name="a2" joint="j2" kv="30"/>
    <general name="a3" joint="j3" gear="3" gainprm="20" biastype="affine" biasprm="0 -20 -0.5"/>
  </actuator>
</mujoco>
"""


def mujoco_log(path: Path, rows: int = 1500) -> pd.DataFrame:
    """The servo arm (:data:`SERVO_ARM`) simulated by MuJoCo itself, its ``mjData`` arrays logged as a user's script
    writes them (``time``, ``qpos[k]``, ``qvel[k]``, ``qacc[k]``, ``ctrl[k]``, ``actuator_force[k]``,
    ``qfrc_actuator[k]``, ``qfrc_bias[k]``, ``qfrc_passive[k]``)."""
    import mujoco

    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    logged = []
    for step in range(rows):
        t = step * model.opt.timestep
        data.ctrl[:] = [0.8 * np.sin(2.0 * t), 0.6 * np.cos(3.0 * t), 0.5 * np.sin(1.5 * t + 0.3)]
        mujoco.mj_step(model, data)
        logged.append({"time": data.time} | {f"{name}[{k}]": float(getattr(data, name)[k]) for k in range(3)
                                             for name in ("qpos", "qvel", "qacc", "ctrl", "actuator_force",
                                                          "qfrc_actuator", "qfrc_bias", "qfrc_passive")})
    return pd.DataFrame(logged)


def test_a_mujoco_log_of_servos_reads_the_actuators_torques_never_their_controls(tmp_path):
    """MuJoCo's own simulation of an arm driven by servos (position, velocity, general with a bias; gears 2, 1, 3)
    logged as ``mjData`` arrays: ``qpos``/``qvel`` read, the torque from ``qfrc_actuator``; without it from
    ``actuator_force`` through the MJCF's gears (equal to MuJoCo's ``qfrc_actuator``, 1e-9); with the controls alone
    the reader refuses (a servo's ``ctrl`` is a setpoint: here far from the force) naming both arrays. At 6ee74d4
    every one was refused naming no column (``qpos`` no quantity)."""
    from dynamics.mjcf import robot_from_mjcf, transmission_from_mjcf
    from dynamics.models import build_model
    from estimation.data.motor_side import read_record_with_transmission

    description = tmp_path / "servo_arm.xml"
    description.write_text(SERVO_ARM)
    robot = robot_from_mjcf(description)
    table = mujoco_log(description)
    torques = table[[f"qfrc_actuator[{k}]" for k in range(3)]].to_numpy()
    assert np.allclose(torques, table[[f"actuator_force[{k}]" for k in range(3)]].to_numpy() * [2.0, 1.0, 3.0])
    assert not np.allclose(torques, table[[f"ctrl[{k}]" for k in range(3)]].to_numpy() * [2.0, 1.0, 3.0], atol=1.0)
    read, said = read_file(table, tmp_path / "mujoco.csv", robot)
    assert np.allclose(read.tau, torques, atol=1e-12) and np.allclose(read.q, table[["qpos[0]", "qpos[1]", "qpos[2]"]])
    vendor = next(message for message in said if "controller's log" in message)
    for part in ("tau from qfrc_actuator[0]..qfrc_actuator[2]", "ctrl[0]..ctrl[2] (commanded controls)",
                 "qfrc_bias[0]..qfrc_bias[2] (no joint", "a measured joint torque is read rather than an actuator"):
        assert part in vendor, (part, vendor)
    forces_only = table.drop(columns=[f"qfrc_actuator[{k}]" for k in range(3)])
    forces_only.to_csv(tmp_path / "forces.csv", index=False, float_format="%.17g")
    model = build_model(robot, "internal", "viscous")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        (segment,) = read_record_with_transmission(tmp_path / "forces.csv", model=model,
                                                   transmission=transmission_from_mjcf(description, robot))
    assert np.allclose(segment.as_recorded.tau, torques, rtol=1e-9, atol=1e-9)
    controls_only = forces_only.drop(columns=[f"actuator_force[{k}]" for k in range(3)])
    with pytest.raises(MissingColumnError, match=r"ctrl\[0\]..ctrl\[2\] are MuJoCo's controls, not forces.*"
                       r"data.qfrc_actuator.*data.actuator_force"):
        read_file(controls_only, tmp_path / "controls.csv", robot)


# ---------------------------------------------------------------- the verbs on each vendor's export (slow)


def _values(path: Path) -> dict[str, np.ndarray]:
    table = pd.read_csv(path)
    return {str(column): table[column].to_numpy(dtype=float) for column in table.columns}


def as_rtde(path: Path) -> None:
    """The lab's record as UR's RTDE recorder writes it (:func:`rtde`): currents, no joint torque."""
    rtde(_values(path)).to_csv(path, index=False, float_format="%.12g")


def as_libfranka(path: Path) -> None:
    """The lab's record as a libfranka robot-state log (:func:`libfranka`), ``", "`` between the header's names."""
    libfranka(_values(path)).to_csv(path, index=False, float_format="%.12g")


def as_lbr_state(path: Path) -> None:
    """The lab's record as KUKA FRI's ``LBRState`` exported with its arrays in cells (:func:`lbr_state`)."""
    lbr_state(_values(path)).to_csv(path, index=False, float_format="%.12g")


def as_abb_egm(path: Path) -> None:
    """The lab's record as an ABB EGM stream flattened to a table (:func:`abb_egm`): angles in degrees, the clock
    in seconds and microseconds since 1970, the plan and the additional axes beside."""
    abb_egm(_values(path)).to_csv(path, index=False, float_format="%.12g")


def as_ros2_joint_state(path: Path) -> None:
    """The lab's record as a ROS 2 ``JointState`` export (:func:`ros2_joint_state`): the stamp split, the arrays in
    cells in the publisher's order, a finger among the joints."""
    from dynamics.robots import load_robot

    ros2_joint_state(_values(path), load_robot("puma560", joints=6).joint_names, 6).to_csv(
        path, index=False, float_format="%.12g")


def vendors():
    from tests.test_unseen_robot_benches import Bench
    from tests.test_unseen_robot_labs import Lab, puma
    from tests.test_unseen_robot_shops import seven_joints
    from tests.test_unseen_robots import Log

    return (
        (Bench(Lab("Universal Robots RTDE recorder (6 joints): actual_q/qd, motor currents through the transmission's "
                   "torque constants, target_moment and target_current beside, 10 s / 4 s / 6 s at 500 Hz", puma(6),
                   *(Log(seconds, 500.0) for seconds in (10.0, 4.0, 6.0)), slow=True)), as_rtde, True),
        (Bench(Lab("libfranka robot state (7 joints): q, dq, tau_J beside tau_J_d, tau_ext_hat_filtered, theta, "
                   "8 s / 3 s / 4 s at 1 kHz", seven_joints, *(Log(seconds, 1000.0) for seconds in (8.0, 3.0, 4.0)),
                   slow=True)), as_libfranka, False),
        (Bench(Lab("KUKA FRI LBRState (7 joints) with arrays in cells: measured position and torque beside the "
                   "commanded, interpolated and external ones, no velocity, 10 s / 4 s / 6 s at 500 Hz", seven_joints,
                   *(Log(seconds, 500.0, velocity=False) for seconds in (10.0, 4.0, 6.0)), slow=True)),
         as_lbr_state, False),
        (Bench(Lab("ABB EGM stream (6 joints): feedBack.joints in degrees, its EgmClock in seconds and microseconds, "
                   "planned.joints and externalJoints beside, torques joined as tau1..tau6, no velocity, "
                   "10 s / 4 s / 6 s at 250 Hz", puma(6),
                   *(Log(seconds, 250.0, velocity=False) for seconds in (10.0, 4.0, 6.0)), slow=True)),
         as_abb_egm, False),
        (Bench(Lab("ROS 2 JointState export (6 joints): header.stamp.sec and nanosec, arrays in cells in the "
                   "publisher's order with a finger, 10 s / 4 s / 6 s at 250 Hz", puma(6),
                   *(Log(seconds, 250.0) for seconds in (10.0, 4.0, 6.0)), slow=True)), as_ros2_joint_state, False),
    )


@pytest.mark.slow
@pytest.mark.parametrize("index", range(5), ids=("ur-rtde", "libfranka", "kuka-fri", "abb-egm", "ros2-split-stamp"))
def test_the_defaults_read_a_vendors_export_and_predict_as_well_as_a_plain_fit(index, tmp_path):
    """Each vendor's export of the lab's records, read without a column map by every verb: the default
    ``oed identify`` and ``oed diagnose``, then ``oed predict`` on the test record, per joint within 1.3x the plain
    fit and in total at most 1.0x (the noise floor's allowance), ``oed predict`` reproducing each verb's reported
    validation error (relative 1e-6), no effect named beyond the truth's. The RTDE export's torques are its
    currents, read through ``--transmission`` (the torque constants) as a motor-side log's."""
    from tests.test_unseen_robot_benches import judged

    bench, rewritten, currents = vendors()[index]
    options: tuple[str, ...] = ()
    if currents:
        transmission = tmp_path / "transmission.json"
        transmission.write_text(json.dumps({"ratios": [1.0] * 6, "torque_constants": list(CURRENT_TO_TORQUE)}))
        options = ("--transmission", str(transmission))
    shift = RTDE_START if currents else (STAMP_START - np.floor(STAMP_START) if index >= 3 else 0.0)
    judged(bench, tmp_path, rewritten, options=options, seconds=(lambda stamps: stamps - shift) if shift else None)


#: the position servos of the slow MJCF case: each joint's gear and the servo's ``kp``, ``kv`` (actuator units)
SERVO_GEARS = (100.0, 100.0, 80.0, 50.0, 50.0, 40.0)
SERVO_KP, SERVO_KV = 40.0, 0.8


def servo_description(urdf: Path, folder: Path) -> Path:
    """The lab's description (its URDF) written as an MJCF with a ``<position>`` servo on each joint
    (:data:`SERVO_GEARS`, ``kp`` :data:`SERVO_KP`, ``kv`` :data:`SERVO_KV`)."""
    from dynamics.mjcf_export import robot_mjcf
    from dynamics.robots import load_robot

    robot = load_robot(urdf=urdf)
    text = robot_mjcf(robot, robot.standard_parameters.reshape(robot.n_joints, -1))
    servos = "".join(f'    <position name="servo{j}" joint="{name}" gear="{gear:g}" kp="{SERVO_KP:g}" kv="{SERVO_KV:g}"/>\n'
                     for j, (name, gear) in enumerate(zip(robot.joint_names, SERVO_GEARS), start=1))
    path = folder / "robot.xml"
    path.write_text(text.replace("</mujoco>", f"  <actuator>\n{servos}  </actuator>\n</mujoco>"))
    return path


def as_mujoco_servos(path: Path) -> None:
    """The lab's record as a script logging MuJoCo's ``mjData`` writes it for the servo description
    (:func:`servo_description`): ``time``, ``qpos[k]``, ``qvel[k]``, ``actuator_force[k]`` (the joint torque over
    the gear) and ``ctrl[k]`` (the setpoint that makes that force: ``kp (ctrl - g q) - kv g q̇ = f``); no
    ``qfrc_actuator``."""
    values = _values(path)
    table = {"time": values["t"]}
    for k, gear in enumerate(SERVO_GEARS):
        q, dq, tau = values[f"q{k + 1}"], values[f"dq{k + 1}"], values[f"tau{k + 1}"]
        table |= {f"qpos[{k}]": q, f"qvel[{k}]": dq, f"actuator_force[{k}]": tau / gear,
                  f"ctrl[{k}]": gear * q + (tau / gear + SERVO_KV * gear * dq) / SERVO_KP}
    frame = pd.DataFrame(table)
    frame.to_csv(path, index=False, float_format="%.12g")


@pytest.mark.slow
def test_a_mujoco_log_of_position_servos_predicts_as_well_as_a_plain_fit(tmp_path):
    """A PUMA 6 described in MJCF with a ``<position>`` servo on each joint (gears 100 to 40), its records logged as
    MuJoCo's ``mjData`` (``qpos``, ``qvel``, ``ctrl`` the setpoints, ``actuator_force`` the servos' forces; 10 s /
    4 s / 6 s at 250 Hz): the default ``oed identify`` and ``oed diagnose`` read the actuator forces through the
    gears, never the controls, then ``oed predict`` on the test record does as well as the plain fit on the joint
    torques, reproducing each reported validation error. At 6ee74d4 every verb exited: no column ``q1`` (``qpos``
    named no quantity)."""
    servo_lab_against_the_plain_fit("PUMA 6 with position servos in MJCF, a MuJoCo log", tmp_path)


def servo_lab_against_the_plain_fit(name: str, tmp_path: Path, *, controls_only: bool = False) -> None:
    """The slow MJCF servo cases' run: a PUMA 6 lab (10 s / 4 s / 6 s at 250 Hz) fitted plainly, its description
    written with :func:`servo_description` and its records as :func:`as_mujoco_servos` logs them (``controls_only``:
    without the ``actuator_force`` columns, the torques left to the servos' laws), then the default verbs against the
    plain fit (:func:`tests.test_unseen_robot_labs.verbs_against_the_plain_fit`, judged by
    :func:`tests.test_unseen_robot_days.checked`). Shared by this file's case and
    :func:`tests.test_logs_as_they_come.test_the_verbs_read_a_mujoco_log_of_servo_controls_with_the_mjcf`."""
    from benchmarks.bench_real_robots import PlainFit
    from tests.test_unseen_robot_days import checked
    from tests.test_unseen_robot_labs import Lab, puma, verbs_against_the_plain_fit, write_records
    from tests.test_unseen_robots import Log

    lab = Lab(name, puma(6), *(Log(seconds, 250.0) for seconds in (10.0, 4.0, 6.0)), slow=True)
    urdf, records, files, spread = write_records(lab, tmp_path)
    plain = PlainFit(["--urdf", str(urdf)])
    cutoff, plain_theta = plain.fit(records["train"], records["validate"], rate_hz=250.0)
    predicted_plain, kept = plain.predict(records["test"], cutoff, plain_theta)
    description = servo_description(urdf, tmp_path)
    for role in ("train", "validate", "test"):
        as_mujoco_servos(files[role])
        if controls_only:
            table = pd.read_csv(files[role])
            table.drop(columns=[column for column in table.columns if column.startswith("actuator_force")]).to_csv(
                files[role], index=False, float_format="%.12g")
    outcome = verbs_against_the_plain_fit(description, files, records["test"], kept, predicted_plain, tmp_path)
    checked(lab.name, {**outcome, "cutoff": cutoff, "floor": (0.02 * spread) ** 2})
