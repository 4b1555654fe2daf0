"""Logs as they come: ROS bags (written with the rosbags package's own writers), .npz and .mat files with a
column map, read into the table of the CSV format and identified as the equivalent CSV is."""

from __future__ import annotations

import json
import sys
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.data.log_formats import (
    LogSource,
    RosSupportError,
    UnknownTopicError,
    parse_column_map,
    read_log_frame,
)
from estimation.data.loading import MissingColumnError
from estimation.data.records import read_record
from oed.cli import main
from oed.fourier import random_fourier
from tests.conftest import TESTS

URDF = TESTS / "data" / "prismatic_arm.urdf"
JOINTS = ("j1", "j2", "j3")
START_NS = 1_732_000_000_123_456_789  # an epoch stamp, as a robot's clock gives


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    """Training and validation CSV files of the prismatic arm (torques with noise, no derivatives)."""
    robot = load_robot(urdf=URDF)
    model = build_model(robot, "internal", "viscous")
    theta = true_parameters(model, seed=3)
    folder = tmp_path_factory.mktemp("logs")
    noise = {"tau1": 0.05, "tau2": 0.5, "tau3": 0.02}
    train = simulate(model, theta, random_fourier(robot, 3), rate_hz=200.0, periods=2, noise=noise, seed=1)
    validate = simulate(model, theta, random_fourier(robot, 4), rate_hz=200.0, periods=2, noise=noise, seed=2)
    replace(train, dq=None, ddq=None).write(folder / "train.csv")  # as a logger gives them: no accelerations
    replace(validate, dq=None, ddq=None).write(folder / "validate.csv")
    return folder


def _rosbags():
    return pytest.importorskip("rosbags", reason="the ros extra (rosbags) is not installed: pip install "
                                                 "'robot-oed[ros]'")


def write_ros2_bag(frame: pd.DataFrame, path, *, storage: str = "mcap", topic: str = "/joint_states",
                   velocity: bool = True) -> None:
    """The table as JointState messages from two publishers per stamp (split joints, another order, joints
    that are not the robot's), with the rosbags package's own writer."""
    _rosbags()
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_HUMBLE)
    joint_state = typestore.types["sensor_msgs/msg/JointState"]
    header, time = typestore.types["std_msgs/msg/Header"], typestore.types["builtin_interfaces/msg/Time"]
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        connection = writer.add_connection(topic, joint_state.__msgtype__, typestore=typestore)
        other = writer.add_connection("/diagnostics_text", "std_msgs/msg/String", typestore=typestore)
        string = typestore.types["std_msgs/msg/String"]
        writer.write(other, START_NS, typestore.serialize_cdr(string(data="hello"), string.__msgtype__))
        for row in frame.itertuples(index=False):
            stamp = START_NS + round(row.t * 1e9)
            stamp_msg = header(stamp=time(sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id="")
            parts = ((["wheel_left", "j3", "j1"], [0.5, row.q3, row.q1], [0.0, row.tau3, row.tau1]),
                     (["j2", "head_pan"], [row.q2, -0.2], [row.tau2, 0.1]))
            for names, position, effort in parts:
                message = joint_state(header=stamp_msg, name=names, position=np.array(position, dtype=float),
                                      velocity=np.array([0.0] * len(names)) if velocity else np.array([], dtype=float),
                                      effort=np.array(effort, dtype=float))
                writer.write(connection, stamp + 1000, typestore.serialize_cdr(message, joint_state.__msgtype__))


def _identify(tmp_path, label, data, validate, *extra):
    out = tmp_path / f"{label}.json"
    assert main(["identify", "--urdf", str(URDF), "--model", "internal", "--friction", "viscous",
                 "--data", str(data), "--validate", str(validate), "--out", str(out), *extra]) == 0
    document = json.loads(out.read_text())
    return np.array([entry["value"] for entry in document["parameters"]]), document


def test_a_ros2_mcap_bag_with_more_joints_in_another_order_identifies_as_the_csv(records, tmp_path):
    frame = pd.read_csv(records / "train.csv")
    bag = tmp_path / "train_bag"
    write_ros2_bag(frame, bag, velocity=False)  # the CSV has no velocity either
    from_csv, _ = _identify(tmp_path, "csv", records / "train.csv", records / "validate.csv")
    from_bag, document = _identify(tmp_path, "bag", bag, records / "validate.csv",
                                   "--joint-names", ",".join(JOINTS))
    np.testing.assert_allclose(from_bag, from_csv, rtol=1e-6, atol=1e-9 * np.abs(from_csv).max())
    # the single .mcap file of the folder, and the URDF's joints when none are named
    single = next(bag.glob("*.mcap"))
    from_file, _ = _identify(tmp_path, "file", single, records / "validate.csv")
    np.testing.assert_allclose(from_file, from_csv, rtol=1e-6, atol=1e-9 * np.abs(from_csv).max())
    assert main(["predict", "--model", str(tmp_path / "bag.json"), "--data", str(single),
                 "--metrics", str(tmp_path / "metrics.json")]) == 0


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_bag_reads_time_position_velocity_effort_by_joint_name(records, tmp_path, storage):
    frame = pd.read_csv(records / "train.csv").iloc[:50]
    bag = tmp_path / f"bag_{storage}"
    write_ros2_bag(frame, bag, storage=storage)
    read = read_log_frame(bag, joint_names=["j2", "j1"])
    assert list(read.columns) == ["t", "q1", "q2", "dq1", "dq2", "tau1", "tau2"]  # velocities of 0 written
    np.testing.assert_allclose(read["t"], frame["t"] - frame["t"].iloc[0], atol=1e-9)
    np.testing.assert_array_equal(read["q1"], frame["q2"])
    np.testing.assert_array_equal(read["tau2"], frame["tau1"])


def test_a_ros1_bag_is_read_too(records, tmp_path):
    _rosbags()
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS1_NOETIC)
    joint_state = typestore.types["sensor_msgs/msg/JointState"]
    header, time = typestore.types["std_msgs/msg/Header"], typestore.types["builtin_interfaces/msg/Time"]
    frame = pd.read_csv(records / "train.csv").iloc[:20]
    path = tmp_path / "run.bag"
    with Writer(path) as writer:
        connection = writer.add_connection("/robot/joint_states", joint_state.__msgtype__, typestore=typestore)
        for index, row in enumerate(frame.itertuples(index=False)):
            stamp = START_NS + round(row.t * 1e9)
            message = joint_state(header=header(seq=index, stamp=time(sec=stamp // 10**9, nanosec=stamp % 10**9),
                                                frame_id=""),
                                  name=list(JOINTS), position=np.array([row.q1, row.q2, row.q3]),
                                  velocity=np.array([], dtype=float), effort=np.array([row.tau1, row.tau2, row.tau3]))
            writer.write(connection, stamp, typestore.serialize_ros1(message, joint_state.__msgtype__))
    read = read_log_frame(LogSource(path, topic="/robot/joint_states"), joint_names=JOINTS)
    assert list(read.columns) == ["t", "q1", "q2", "q3", "tau1", "tau2", "tau3"]
    np.testing.assert_array_equal(read["q3"], frame["q3"])


def test_an_absent_topic_names_the_topics_and_types_the_bag_holds(records, tmp_path):
    bag = tmp_path / "bag"
    write_ros2_bag(pd.read_csv(records / "train.csv").iloc[:5], bag, topic="/arm/joint_states")
    with pytest.raises(UnknownTopicError, match=r"'/joint_states'.*/arm/joint_states \(sensor_msgs/msg/JointState\)"
                                                r".*/diagnostics_text \(std_msgs/msg/String\)"):
        read_log_frame(bag, joint_names=JOINTS)
    with pytest.raises(MissingColumnError, match="gripper.*messages name head_pan, j1, j2, j3, wheel_left"):
        read_log_frame(LogSource(bag, topic="/arm/joint_states"), joint_names=["j1", "gripper"])
    code = main(["identify", "--urdf", str(URDF), "--data", str(bag), "--out", str(tmp_path / "r.json")])
    assert code == 2


def test_without_the_ros_extra_the_error_names_it(records, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "rosbags.highlevel", None)  # an import of it fails, as when not installed
    (tmp_path / "run.mcap").write_bytes(b"")
    with pytest.raises(RosSupportError, match=r"robot-oed\[ros\]"):
        read_log_frame(tmp_path / "run.mcap", joint_names=JOINTS)


def test_npz_and_mat_with_a_column_map_read_as_the_csv(records, tmp_path):
    from scipy.io import savemat

    frame = pd.read_csv(records / "train.csv")
    arrays = {"times": frame["t"].to_numpy(), "positions": frame[["q1", "q2", "q3"]].to_numpy(),
              "torques": frame[["tau1", "tau2", "tau3"]].to_numpy(), "label": np.array("run 1")}
    np.savez(tmp_path / "run.npz", **arrays)
    savemat(tmp_path / "run.mat", {"times": arrays["times"][:, None], "positions": arrays["positions"].T,
                                   "volts": arrays["torques"] / 35.15})
    columns = parse_column_map("t=times,q=positions,tau=torques")
    model = build_model(load_robot(urdf=URDF), "internal", "viscous")
    expected = read_record(records / "train.csv", model=model)[0]
    for source in (LogSource(tmp_path / "run.npz", columns=columns),
                   LogSource(tmp_path / "run.mat", columns={"t": "times", "q": "positions", "tau": "35.15*volts"})):
        segment = read_record(source, model=model)[0]
        np.testing.assert_array_equal(segment.t, expected.t)
        np.testing.assert_array_equal(segment.q, expected.q)
        np.testing.assert_allclose(segment.tau, expected.tau, rtol=1e-12, atol=1e-12)
    with pytest.raises(MissingColumnError, match="no array 'speeds'.*positions, times, torques"):
        read_log_frame(LogSource(tmp_path / "run.npz", columns={"t": "times", "q": "speeds"}))


def test_cli_columns_rename_a_table_and_identify_as_the_csv(records, tmp_path):
    frame = pd.read_csv(records / "train.csv")
    frame.rename(columns={"t": "Time", **{f"q{i}": f"Pos{i}" for i in (1, 2, 3)},
                          **{f"tau{i}": f"Torque{i}" for i in (1, 2, 3)}}).to_csv(tmp_path / "renamed.csv", index=False)
    validate = pd.read_csv(records / "validate.csv")
    np.savez(tmp_path / "validate.npz", Time=validate["t"].to_numpy(), Pos=validate[["q1", "q2", "q3"]].to_numpy(),
             Torque=validate[["tau1", "tau2", "tau3"]].to_numpy())
    from_csv, _ = _identify(tmp_path, "csv", records / "train.csv", records / "validate.csv")
    renamed, _ = _identify(tmp_path, "renamed", tmp_path / "renamed.csv", tmp_path / "validate.npz",
                           "--columns", "t=Time,q=Pos,tau=Torque")
    np.testing.assert_allclose(renamed, from_csv, rtol=1e-12)


@pytest.mark.realdata
def test_real_npz_and_mat_files_read_with_a_column_map():
    """The KUKA LWR4+ runs (.npz) and the EMPS benchmark (.mat, force = 35.15 N/V · vir) without a converter."""
    from scipy.io import loadmat

    from tests.conftest import shared_data

    kuka = shared_data("kuka_lwr4", "kuka_lwr4_HW_measurements_1.npz")
    frame = read_log_frame(LogSource(kuka, columns=parse_column_map("t=times,q=positions,dq=velocities,tau=torques")))
    with np.load(kuka) as arrays:
        np.testing.assert_array_equal(frame[[f"tau{i}" for i in range(1, 8)]].to_numpy(), arrays["torques"])
    emps = shared_data("emps", "DATA_EMPS.mat")
    model = build_model(load_robot("emps"), "internal", "viscous")
    segment = read_record(LogSource(emps, columns={"t": "t", "q": "qm", "tau": "35.15*vir"}), model=model)[0]
    np.testing.assert_allclose(segment.tau[:, 0], 35.15 * loadmat(emps)["vir"].ravel(), rtol=1e-15)


def test_the_streamed_path_refuses_a_bag_by_name(records, tmp_path, capsys):
    bag = tmp_path / "bag"
    write_ros2_bag(pd.read_csv(records / "train.csv"), bag)
    assert main(["identify", "--urdf", str(URDF), "--data", str(bag), "--validate", str(records / "validate.csv"),
                 "--chunk-size", "500", "--out", str(tmp_path / "r.json")]) == 2
    assert "the streamed path (chunks, workers, a cluster) reads .csv and .parquet" in capsys.readouterr().err
