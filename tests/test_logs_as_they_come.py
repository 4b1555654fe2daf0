"""Logs as they come, the cases h-logs2 and h-unseen16 left open (h-logs3): a log written newest first, ABB EGM's
``header.tm`` as its only clock, torques held at a lower rate than the positions (each value repeated on the rows
between two samples), a MuJoCo servo's force computed from its controls and the state with the MJCF given."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from tests.test_unseen_robots import FRICTION, Log, truth, urdf_of, write_record


@pytest.fixture(scope="module")
def puma3(tmp_path_factory):
    """A PUMA's first three joints, one clean 2 s record at 250 Hz (no velocity column) and its model."""
    folder = tmp_path_factory.mktemp("puma3")
    urdf = urdf_of("puma560:3", folder)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    write_record(model, truth(model), Log(2.0, 250.0, velocity=False), 11, folder / "clean.csv")
    return model, folder / "clean.csv"


def read_quietly(path, model):
    from estimation.data.records import read_measurements

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        read = read_measurements(path, model=model)
    return read, [str(warning.message) for warning in caught], [warning.category for warning in caught]


def test_a_log_written_newest_first_is_read_reversed_and_said(puma3, tmp_path):
    """Every time step negative (a ring buffer dumped from its latest entry): read reversed, equal to the same log
    oldest first, in a ``NewestFirstWarning``; at 6d10335 it was refused ("decreases … sort the samples"). Rows out of
    order (shuffled) stay an error naming the rows; the streamed reader (chunk by chunk) reads the newest-first log
    from the file's end to the same samples (until h-logs4 it refused it, naming the in-memory reader)."""
    from estimation.data import NewestFirstWarning, TimeBaseError
    from estimation.data.records import read_measurements
    from estimation.streaming.chunks import read_chunks, segment_sources

    model, clean = puma3
    table = pd.read_csv(clean)
    table.iloc[::-1].to_csv(tmp_path / "newest_first.csv", index=False, float_format="%.17g")
    expected, _, _ = read_quietly(clean, model)
    read, said, kinds = read_quietly(tmp_path / "newest_first.csv", model)
    assert NewestFirstWarning in kinds, said
    assert any("written newest first, read reversed" in message for message in said), said
    for name in ("t", "q", "tau"):
        assert np.array_equal(getattr(read, name), getattr(expected, name)), name
    shuffled = table.sample(frac=1.0, random_state=3)
    shuffled.to_csv(tmp_path / "shuffled.csv", index=False)
    rows = np.flatnonzero(np.diff(shuffled["t"].to_numpy()) < 0)
    with pytest.raises(TimeBaseError, match=rf"decreases at row {rows[0] + 1} .* other row\(s\): {rows[1] + 1} \(.*"
                                            r"rows out of order \(neither oldest nor newest first\); sort the samples"):
        read_measurements(tmp_path / "shuffled.csv", model=model)
    with warnings.catch_warnings():  # since h-logs4 the streamed reader reads it from the file's end
        warnings.simplefilter("ignore")
        sources = segment_sources([tmp_path / "newest_first.csv"], model, chunk_size=100)
        chunks = [chunk for source in sources for chunk in read_chunks(source, model, chunk_size=100)]
    for name in ("t", "q", "tau"):
        assert np.array_equal(np.concatenate([getattr(chunk, name) for chunk in chunks]), getattr(expected, name))


def test_abb_egm_header_tm_alone_is_read_as_milliseconds(tmp_path):
    """An EGM table whose only clock is the message header's ``tm`` (egm.proto: milliseconds; no ``EgmClock``
    ``feedBack.time``): read as the time in seconds, said with the map that reads it so (which reads the same
    values). At 6d10335 it was refused: "missing column(s) t". A plan's header (``planned.header.tm``) is no clock of
    the samples."""
    from dynamics.robots import load_robot
    from estimation.data import MissingColumnError
    from tests.test_vendor_logs import abb_egm, read_file, said_map, signals

    values = signals(6, rows=200)
    robot = load_robot("puma560", joints=6)
    table = abb_egm(values).drop(columns=["feedBack.time.sec", "feedBack.time.usec", "planned.time.sec",
                                          "planned.time.usec"])
    table["header.tm"] += 7_200_000  # two hours since the controller started
    read, said = read_file(table, tmp_path / "egm.csv", robot)
    assert np.allclose(read.t, values["t"] + 7200.0, atol=1e-9) and np.allclose(read.tau[:, 2], values["tau3"])
    assert any("ABB EGM's header stamp header.tm, milliseconds by its protocol (--columns 't=0.001*header.tm')"
               in message for message in said), said
    mapped, _ = read_file(table, tmp_path / "egm.csv", robot, columns=said_map(said, "controller's log"))
    assert np.array_equal(mapped.t, read.t) and np.array_equal(mapped.q, read.q)
    with pytest.raises(MissingColumnError, match="missing column"):
        read_file(table.rename(columns={"header.tm": "planned.header.tm"}), tmp_path / "plan.csv", robot)


def held_torques(table: pd.DataFrame, every: int) -> pd.DataFrame:
    """``table`` with its torques sampled at ``1/every`` of the positions' rate and each value repeated on the rows
    up to the next sample (a drive's slower channel merged by holding its last value, not by blanks)."""
    rows = np.arange(len(table))
    held = table.copy()
    columns = [column for column in table.columns if column.startswith("tau")]
    held[columns] = table[columns].to_numpy()[rows - rows % every]
    return held


@pytest.mark.parametrize("every", [2, 3])
def test_torques_held_at_a_lower_rate_are_read_as_that_rate_in_memory_and_streamed(puma3, tmp_path, every):
    """Torques sampled at a half (a third) of the positions' rate, each value repeated until the next (h-unseen16's
    ``held`` logger): the repeats are read as the channel's blanks, each hold's first row its sample, in a
    ``HeldChannelWarning``, in memory and chunk by chunk alike (chunks of 100 rows: the hold across their edges).
    The repeats are masked in the torques only (NaN), every row's positions kept, in memory (h-heldmask; h-logs3
    dropped the whole rows) and streamed alike (h-streammask2; before, the streamed reader dropped the rows: its
    grid at the held rate). At 6d10335 every repeat was read as a sample (a lag of half a hold the diagnosis then
    explained)."""
    from estimation.data import HeldChannelWarning
    from estimation.streaming.chunks import read_chunks

    model, clean = puma3
    table = held_torques(pd.read_csv(clean), every)
    table.to_csv(tmp_path / "held.csv", index=False, float_format="%.17g")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        from estimation.data.records import read_measurements

        memory = read_measurements(tmp_path / "held.csv", model=model)
        chunks = list(read_chunks(tmp_path / "held.csv", model, chunk_size=100))
    said = [str(item.message) for item in caught if issubclass(item.category, HeldChannelWarning)]
    masked = len(table) - len(range(0, len(table), every))
    assert len(said) == 2 and all(f"joint torques (tau) new every {every} rows" in text and
                                  f"the {masked} row(s) of {len(table)} where a measured channel repeats keep" in text
                                  for text in said), said
    kept = np.arange(0, len(table), every)
    tau = table[["tau1", "tau2", "tau3"]].to_numpy()
    assert np.array_equal(memory.as_recorded.t, table["t"].to_numpy())
    assert np.array_equal(memory.as_recorded.q, table[["q1", "q2", "q3"]].to_numpy())
    samples = ~np.isnan(memory.as_recorded.tau)
    assert np.array_equal(np.flatnonzero(samples.all(axis=1)), kept) and not samples[~samples.all(axis=1)].any()
    assert np.array_equal(memory.as_recorded.tau[kept], tau[kept])
    assert np.allclose(np.concatenate([chunk.t for chunk in chunks]), memory.t, rtol=0, atol=1e-12)
    assert np.array_equal(np.vstack([chunk.q for chunk in chunks]), memory.q)
    assert np.array_equal(np.vstack([chunk.tau for chunk in chunks]), memory.tau, equal_nan=True)


def test_a_quantised_torque_or_stale_rows_are_no_hold(puma3, tmp_path):
    """What repeats without a hold is read as before: a torque quantised coarsely (0.5 N·m: its values repeat on
    runs of irregular length as the signal crosses its levels) and a few stale rows (the Panda's logger: 92 rows of
    20 544 whose torques repeat the previous row's while the positions moved)."""
    from estimation.data.held_channels import held_rows

    model, clean = puma3
    table = pd.read_csv(clean)
    n = model.robot.n_joints
    quantised = table.copy()
    quantised[["tau1", "tau2", "tau3"]] = np.round(table[["tau1", "tau2", "tau3"]] / 0.5) * 0.5
    found = held_rows(quantised, n)
    assert not found.holds and not found.rows.any()
    stale = table.copy()
    rows = np.arange(5, len(table), 23)
    stale.loc[rows, ["tau1", "tau2", "tau3"]] = table.loc[rows - 1, ["tau1", "tau2", "tau3"]].to_numpy()
    assert not held_rows(stale, n).holds
    assert held_rows(held_torques(table, 2), n).holds == (("tau", 2),)


def servo_log(path, rows: int = 1500) -> pd.DataFrame:
    """The servo arm of ``path`` (an MJCF) simulated by MuJoCo itself, each row its state, controls and MuJoCo's
    own forces at that state (``mj_forward`` before each step: the force the step applies), as ``mjData`` names."""
    import mujoco

    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    logged = []
    for step in range(rows):
        t = step * model.opt.timestep
        data.ctrl[:] = [0.8 * np.sin(2.0 * t), 0.6 * np.cos(3.0 * t), 0.5 * np.sin(1.5 * t + 0.3)]
        mujoco.mj_forward(model, data)
        logged.append({"time": data.time} | {f"{name}[{k}]": float(getattr(data, name)[k]) for k in range(3)
                                             for name in ("qpos", "qvel", "ctrl", "actuator_force", "qfrc_actuator")})
        mujoco.mj_step(model, data)
    return pd.DataFrame(logged)


def test_a_mujoco_servos_force_is_computed_from_its_controls_with_the_mjcf(tmp_path):
    """A MuJoCo log of a servo arm's controls and state only (``qpos``, ``qvel``, ``ctrl``: no ``actuator_force``
    nor ``qfrc_actuator``): with the MJCF given (its transmission from the ``<actuator>`` elements) the joint torques
    are computed by the actuators' laws (a ``<position>`` servo with gear 2, its control and force clamped to their
    ranges; a ``<velocity>`` servo; a ``<general>`` with an affine bias, gear 3) and equal MuJoCo's
    ``qfrc_actuator`` (1e-9), said in a ``ServoForcesWarning``; the laws survive a model file's transmission (JSON).
    Without the MJCF the log stays refused naming the force arrays; a servo whose control is filtered
    (``timeconst``: an activation state) is refused with the MJCF too. At 6d10335 every one was refused."""
    from dynamics.mjcf import robot_from_mjcf, transmission_from_mjcf
    from dynamics.transmission_files import transmission_from_json
    from estimation.data import MissingColumnError, ServoForcesWarning
    from estimation.data.motor_side import read_record_with_transmission
    from tests.test_vendor_logs import SERVO_ARM, read_file

    description = tmp_path / "servo_arm.xml"
    description.write_text(SERVO_ARM.replace('kv="20" gear="2"', 'kv="20" gear="2" ctrlrange="-0.5 0.5" '
                                             'forcerange="-5 5"'))
    robot = robot_from_mjcf(description)
    table = servo_log(description)
    torques = table[[f"qfrc_actuator[{k}]" for k in range(3)]].to_numpy()
    controls_only = table.drop(columns=[f"{name}[{k}]" for name in ("actuator_force", "qfrc_actuator")
                                        for k in range(3)])
    controls_only.to_csv(tmp_path / "controls.csv", index=False, float_format="%.17g")
    forces = table[[f"actuator_force[{k}]" for k in range(3)]].to_numpy()
    assert np.abs(forces[:, 0]).max() == 5.0  # the position servo's force clamped at its range
    model = build_model(robot, "internal", "viscous")
    transmission = transmission_from_mjcf(description, robot)
    for given in (transmission, transmission_from_json(transmission.to_dict(), robot)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            (segment,) = read_record_with_transmission(tmp_path / "controls.csv", model=model, transmission=given)
        said = [str(item.message) for item in caught if issubclass(item.category, ServoForcesWarning)]
        assert len(said) == 1 and "computed from the servos' controls ctrl1..ctrl3" in said[0], said
        assert np.allclose(segment.as_recorded.tau, torques, rtol=1e-9, atol=1e-9)
    with pytest.raises(MissingColumnError, match=r"ctrl\[0\]..ctrl\[2\] are MuJoCo's controls, not forces.*"
                       r"data.qfrc_actuator.*data.actuator_force"):
        read_file(controls_only, tmp_path / "alone.csv", robot)
    no_velocity = controls_only.drop(columns=[f"qvel[{k}]" for k in range(3)])
    no_velocity.to_csv(tmp_path / "no_velocity.csv", index=False, float_format="%.17g")
    warnings.simplefilter("ignore")  # (the reader's notes on the time column: said in the cases above)
    with pytest.raises(MissingColumnError, match="depend on the joints' velocities .* log data.qvel"):
        read_record_with_transmission(tmp_path / "no_velocity.csv", model=model, transmission=transmission)
    filtered = tmp_path / "filtered.xml"
    filtered.write_text(SERVO_ARM.replace('kv="20" gear="2"', 'kv="20" gear="2" timeconst="0.05"'))
    with pytest.raises(MissingColumnError, match="MuJoCo's controls, not forces"):
        read_record_with_transmission(tmp_path / "controls.csv", model=model,
                                      transmission=transmission_from_mjcf(filtered, robot_from_mjcf(filtered)))


@pytest.mark.slow
def test_the_verbs_read_a_mujoco_log_of_servo_controls_with_the_mjcf(tmp_path):
    """:func:`tests.test_vendor_logs.test_a_mujoco_log_of_position_servos_predicts_as_well_as_a_plain_fit`'s PUMA 6
    with a ``<position>`` servo on each joint (gears 100 to 40, ``kp`` 40, ``kv`` 0.8), its records logged with
    ``qpos``, ``qvel`` and the servos' ``ctrl`` only (no ``actuator_force``, no ``qfrc_actuator``), the MJCF given as
    ``--urdf``: the default ``oed identify`` and ``oed diagnose`` compute the joint torques from the controls by the
    servos' laws and, then ``oed predict`` on the test record, do as well as the plain fit on the joint torques,
    reproducing each reported validation error. At 6d10335 every verb exited naming the force arrays."""
    from tests.test_vendor_logs import servo_lab_against_the_plain_fit

    servo_lab_against_the_plain_fit("PUMA 6 with position servos in MJCF, a MuJoCo log of the controls", tmp_path,
                                    controls_only=True)


def test_a_held_velocity_column_drops_its_repeats_rows(puma3, tmp_path):
    """A velocity column held at half the positions' rate (``dq`` new every 2 rows): no per-channel mask holds an
    input of the regressor, so its repeats' rows are dropped whole (positions and torques with them), as h-logs3 read
    every held channel; the torques at full rate are no hold and nothing of them is masked."""
    from estimation.data.held_channels import held_rows

    model, clean = puma3
    table = pd.read_csv(clean)
    rows = np.arange(len(table))
    t = table["t"].to_numpy()
    for joint in range(1, 4):
        table[f"dq{joint}"] = np.gradient(table[f"q{joint}"].to_numpy(), t)[rows - rows % 2]
    found = held_rows(table, model.robot.n_joints)
    assert found.holds == (("dq", 2),) and np.array_equal(found.dropped_rows, rows % 2 == 1)
    table.to_csv(tmp_path / "held_dq.csv", index=False, float_format="%.17g")
    read, said, _ = read_quietly(tmp_path / "held_dq.csv", model)
    assert any("velocities (dq) new every 2 rows" in text and "read as that channel's blanks" in text
               for text in said), said
    record = read.as_recorded
    assert np.array_equal(record.t, t[rows % 2 == 0]) and not np.isnan(record.tau).any()


def test_held_repeats_stay_on_their_rows_when_other_rows_are_dropped(puma3, tmp_path):
    """The held torques' mask follows the rows the reader drops after judging the hold: a torque channel that starts
    four rows late (the edge rows left out, :class:`UnstartedChannelsWarning`) and a dropout row (every data cell empty) leave the NaN exactly on the
    repeats of the rows kept, each held sample's value as logged."""
    model, clean = puma3
    table = held_torques(pd.read_csv(clean), 2)
    columns = ["tau1", "tau2", "tau3"]
    table.loc[:3, "tau1"] = np.nan  # one torque channel reports from row 4: the rows before it left out
    table.loc[101, ["q1", "q2", "q3", *columns]] = np.nan
    table.to_csv(tmp_path / "held_edges.csv", index=False, float_format="%.17g")
    read, said, categories = read_quietly(tmp_path / "held_edges.csv", model)
    assert any("new every 2 rows" in text for text in said), said
    assert {"UnstartedChannelsWarning", "BlankRowsWarning"} <= {category.__name__ for category in categories}
    rows = np.setdiff1d(np.arange(4, len(table)), [101])
    record = read.as_recorded
    assert np.array_equal(record.t, table["t"].to_numpy()[rows])
    masked = np.isnan(record.tau).all(axis=1)
    assert np.array_equal(masked, rows % 2 == 1) and not np.isnan(record.tau[~masked]).any()
    assert np.array_equal(record.tau[~masked], table[columns].to_numpy()[rows[~masked]])
