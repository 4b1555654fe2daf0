"""Sensor faults a user's log holds, read as such by the readers (h-unseen13's two strict xfails in
``tests/test_unseen_robot_users.py``, 2.68x and 50.9x the plain fit before; h-sensorfaults2: read errors of
several samples, a clipped wrench channel, the streamed reader's clipped-sensor check):

- **encoder read errors**: one sample of one joint's position off (a bit error on the encoder's bus), or a run of
  two to five, the next right again. A step into that value and out of it, each longer than the joint can travel in a sample period, is
  a dropout (:func:`estimation.data.log_cleaning.encoder_glitches`), said in an ``EncoderGlitchWarning`` naming the
  rows and joints; the streamed scan decides it on the whole record alike, at its chunk edges too. A fast true
  motion, an angle wrapped at ±π and a quantised encoder flickering between counts are none.
- **a torque sensor past its range**: a channel holding its extreme value on runs of samples while its joint moves,
  and far more often than its other values (:func:`estimation.data.log_cleaning.saturated_samples`), is clipped
  there: said in a ``SaturatedTorqueWarning``, its samples left out of the samples as recorded (every error) and of
  the fit. A quantised channel (its extremes repeat no more than its other values) and a joint at rest against a
  hard stop (the torque held while the position holds) are none. A wrench channel alike (while any joint moves).
  The streamed reader judges it block by block as memory does on the whole record, and says it.

Each against something independent: the record as simulated before the fault, the rows the fault was put on, the
streamed reader against the one in memory; and, on the four real robots' logs (``../shared/data``), nothing said.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tests.conftest import shared_data
from tests.test_unseen_robots import Log

#: the rows given an encoder read error: the last row of the first 250-row chunk, the first of the next, one inside
GLITCHES = ((249, 1, 0.2), (250, 0, -0.2), (611, 2, 0.15))
#: the chunk sizes the streamed reader is tried with: a glitch on a chunk's last row and the next one's first (250),
#: on the last row of one and in the middle of the next (251)
CHUNK_SIZES = (250, 251)


def _puma_record(tmp_path: Path, name: str = "clean.csv", seconds: float = 3.0):
    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from tests.test_unseen_robots import FRICTION, truth, urdf_of, write_record

    urdf = urdf_of("puma560:3", tmp_path)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    write_record(model, truth(model), Log(seconds, 250.0, velocity=False), 11, tmp_path / name)
    return model, tmp_path / name


def _caught(category, call):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        value = call()
    return value, [str(item.message) for item in caught if issubclass(item.category, category)]


def test_an_encoder_read_error_is_a_dropout_named_by_row_and_joint_alike_in_memory_and_streamed(tmp_path):
    from estimation.data import EncoderGlitchWarning
    from estimation.data.records import read_measurements

    model, clean = _puma_record(tmp_path)
    table = pd.read_csv(clean)
    for row, joint, jump in GLITCHES:
        table.loc[row, f"q{joint + 1}"] += jump
    table.to_csv(tmp_path / "glitches.csv", index=False, float_format="%.10g")
    table = pd.read_csv(tmp_path / "glitches.csv")  # as written
    memory, said = _caught(EncoderGlitchWarning, lambda: read_measurements(tmp_path / "glitches.csv", model=model))
    assert len(said) == 1, said
    for row, joint, _ in GLITCHES:
        assert f"row {row} (t = {table['t'][row]:.6g} s, q{joint + 1}" in said[0], said
    kept = np.setdiff1d(np.arange(len(table)), [row for row, _, _ in GLITCHES])
    recorded = memory.as_recorded
    assert np.allclose(recorded.t, table["t"].to_numpy()[kept], rtol=0, atol=1e-12)  # the rows dropped, no other
    assert np.allclose(recorded.q, table[["q1", "q2", "q3"]].to_numpy()[kept], rtol=0, atol=1e-12)
    # the dropped samples bridged from their neighbours: near the clean record, far from the glitch
    truth = pd.read_csv(clean)[["q1", "q2", "q3"]].to_numpy()
    on_grid = np.searchsorted(memory.t, table["t"].to_numpy()[[row for row, _, _ in GLITCHES]])
    assert np.abs(memory.q[on_grid] - truth[[row for row, _, _ in GLITCHES]]).max() < 0.01
    _streamed_as_memory(tmp_path / "glitches.csv", model, memory, said)
    # a description without velocity limits: the record's own fast speed bounds the steps; the same rows
    unlimited = replace(model.robot, joints=tuple(replace(joint, velocity=np.inf) for joint in model.robot.joints))
    from dynamics.models import build_model
    from tests.test_unseen_robots import FRICTION
    bare = build_model(unlimited, "internal", FRICTION)
    _, said_bare = _caught(EncoderGlitchWarning, lambda: read_measurements(tmp_path / "glitches.csv", model=bare))
    assert len(said_bare) == 1 and all(f"row {row} " in said_bare[0] for row, _, _ in GLITCHES), said_bare
    _, nothing = _caught(EncoderGlitchWarning, lambda: read_measurements(clean, model=model))
    assert nothing == []


def _streamed_as_memory(path: Path, model, memory, said: list[str]) -> None:
    """The streamed reader at :data:`CHUNK_SIZES` says what memory said (``said``) and gives its t, q and tau."""
    from estimation.data import EncoderGlitchWarning
    from estimation.streaming.chunks import read_chunks

    for chunk_size in CHUNK_SIZES:
        streamed, said_streamed = _caught(EncoderGlitchWarning, lambda size=chunk_size: list(read_chunks(
            path, model, chunk_size=size)))
        assert said_streamed == said, (chunk_size, said_streamed)
        for name in ("t", "q", "tau"):
            joined = np.concatenate([getattr(chunk, name) for chunk in streamed])
            assert joined.shape == getattr(memory, name).shape
            assert np.max(np.abs(joined - getattr(memory, name))) < 1e-9, (chunk_size, name)


def _judged(q, t, limit):
    from estimation.data.log_cleaning import encoder_glitches, position_steps

    return encoder_glitches(position_steps(q, t, np.asarray(limit, dtype=float)), np.asarray(limit, dtype=float))


def test_a_fast_motion_a_wrapped_angle_and_a_quantised_encoder_are_no_read_errors():
    generator = np.random.default_rng(3)
    t = np.arange(5000) / 1000.0
    # a fast true motion: 1.9 times the joint's velocity limit of 2 rad/s at its peak, reversing 40 times
    fast = 0.095 * np.sin(2 * np.pi * 4.0 * t) + 1e-4 * generator.standard_normal(t.shape)
    rows, _ = _judged(fast[:, None], t, [2.0])
    assert rows.size == 0, rows
    rows, _ = _judged(fast[:, None], t, [np.inf])  # judged by the record's own fast speed
    assert rows.size == 0, rows
    # an angle wrapped at ±π, the joint hovering across it: every sample leaves and comes back by a whole turn
    hovering = np.pi + 0.003 * np.sin(2 * np.pi * 30.0 * t) + 1e-4 * generator.standard_normal(t.shape)
    wrapped = np.mod(hovering + np.pi, 2 * np.pi) - np.pi
    assert np.sum(np.abs(np.diff(wrapped)) > np.pi) > 100  # it does cross
    for limit in ([2.0], [np.inf]):
        rows, _ = _judged(wrapped[:, None], t, limit)
        assert rows.size == 0, rows
    # a quantised encoder (0.3 degree counts) at rest, its count flickering: one count is 5.2 mrad, more than the
    # 4 mrad twice a 2 rad/s limit allows in 1 ms
    count = np.deg2rad(0.3)
    still = count * np.round(0.3 + 0.25 * generator.standard_normal(t.shape))
    assert np.sum(np.diff(still) != 0) > 500
    for limit in ([2.0], [np.inf]):
        rows, _ = _judged(still[:, None], t, limit)
        assert rows.size == 0, rows
    # ... and a read error on it is one
    glitched = still.copy()
    glitched[1234] += 0.2
    rows, joints = _judged(np.column_stack([still, glitched]), t, [2.0, 2.0])
    assert rows.tolist() == [1234] and joints.tolist() == [1], (rows, joints)


#: read errors lasting several samples: (first row, joint, samples, jump); the first across the 250-row chunks' edge,
#: the last ending on the 251-row chunks' last row
READ_RUNS = ((247, 1, 4, 0.2), (400, 0, 2, -0.2), (600, 2, 5, 0.15), (498, 1, 3, -0.25))


def test_read_errors_lasting_several_samples_are_dropouts_alike_in_memory_and_streamed(tmp_path):
    """Two to five samples of one joint off, then right again (a stale or corrupted reading held a few samples):
    each of their rows a dropout, named, as one sample's read error is; the streamed scan, its runs across a chunk's
    edge, alike."""
    from estimation.data import EncoderGlitchWarning
    from estimation.data.records import read_measurements

    model, clean = _puma_record(tmp_path)
    table = pd.read_csv(clean)
    for row, joint, length, jump in READ_RUNS:
        table.loc[row:row + length - 1, f"q{joint + 1}"] += jump
    table.to_csv(tmp_path / "runs.csv", index=False, float_format="%.10g")
    table = pd.read_csv(tmp_path / "runs.csv")
    off = sorted(row + k for row, _, length, _ in READ_RUNS for k in range(length))
    memory, said = _caught(EncoderGlitchWarning, lambda: read_measurements(tmp_path / "runs.csv", model=model))
    assert len(said) == 1 and f"dropped {len(off)} row(s)" in said[0], said
    kept = np.setdiff1d(np.arange(len(table)), off)
    recorded = memory.as_recorded
    assert np.allclose(recorded.t, table["t"].to_numpy()[kept], rtol=0, atol=1e-12)  # those rows, no other
    truth = pd.read_csv(clean)[["q1", "q2", "q3"]].to_numpy()
    on_grid = np.searchsorted(memory.t, table["t"].to_numpy()[off])
    assert np.abs(memory.q[on_grid] - truth[off]).max() < 0.02  # bridged from the samples around: near the truth
    _streamed_as_memory(tmp_path / "runs.csv", model, memory, said)


def test_runs_of_samples_a_hard_stop_a_step_that_stays_and_a_quantised_encoder_are_judged_apart():
    """What a run of samples off is not: a joint stopped hard (its speed falls from the limit to nothing in a
    sample), one bouncing off a stop, a position that steps and stays (a re-referenced zero), a quantised encoder
    flickering for a few samples; and a run longer than five samples is not judged (a stall, a motion)."""
    generator = np.random.default_rng(4)
    t = np.arange(3000) / 1000.0
    noise = 1e-5 * generator.standard_normal(t.shape)
    # moving at 0.95 of a 2 rad/s limit, stopped hard at t = 1 s, then back out at t = 2 s
    stopped = np.where(t < 1.0, 1.9 * t, np.where(t < 2.0, 1.9, 1.9 - 1.9 * (t - 2.0))) + noise
    # bouncing off a stop: in at 1.9 rad/s (0.95 of the limit), out at 1.5 rad/s, each sample
    bounce = np.where(t < 1.0, 1.9 * t, 1.9 - 1.5 * (t - 1.0)) + noise
    # a step that stays: the position re-referenced by 0.3 rad at t = 1.5 s
    stepped = 0.2 * np.sin(2 * np.pi * 0.5 * t) + np.where(t >= 1.5, 0.3, 0.0) + noise
    for limit in (2.0, np.inf):
        rows, joints = _judged(np.column_stack([stopped, bounce, stepped]), t, [limit] * 3)
        assert rows.size == 0, (limit, rows, joints)
    # a quantised encoder at rest whose count flickers for runs of two to five samples
    count = np.deg2rad(0.3)
    flicker = np.zeros(t.shape)
    for start in range(100, 2900, 97):
        flicker[start:start + 2 + start % 4] = count
    for limit in (2.0, np.inf):
        rows, _ = _judged(flicker[:, None], t, [limit])
        assert rows.size == 0, (limit, rows)
    # the same encoder with read errors of 2, 5 and 6 samples: the first two found, the third not (longer than five)
    read = flicker.copy()
    read[500:502] += 0.2
    read[1500:1505] -= 0.2
    read[2500:2506] += 0.2
    rows, joints = _judged(read[:, None], t, [2.0])
    assert rows.tolist() == [500, 501, *range(1500, 1505)] and set(joints.tolist()) == {0}, rows


def test_a_clipped_torque_sensor_is_named_and_its_samples_masked_in_that_channel_only(tmp_path):
    from estimation.data import SaturatedTorqueWarning
    from estimation.data.records import read_measurements

    model, clean = _puma_record(tmp_path)
    table = pd.read_csv(clean)
    limit = 0.8 * float(np.abs(table["tau2"]).max())
    clipped = table.assign(tau2=np.clip(table["tau2"], -limit, limit))
    clipped.to_csv(tmp_path / "clipped.csv", index=False, float_format="%.10g")
    clipped = pd.read_csv(tmp_path / "clipped.csv")  # as written
    at_limit = np.flatnonzero(np.abs(clipped["tau2"].to_numpy()) >= limit * (1 - 1e-9))
    assert at_limit.size > 20
    memory, said = _caught(SaturatedTorqueWarning, lambda: read_measurements(tmp_path / "clipped.csv", model=model))
    assert len(said) == 1 and "tau2" in said[0] and "tau1" not in said[0] and "tau3" not in said[0], said
    recorded = memory.as_recorded
    # tau2's clipped samples masked (NaN: estimation.data.channel_mask), tau2's only: tau1's and tau3's readings of
    # those samples kept, as every position
    assert np.allclose(recorded.t, table["t"].to_numpy(), rtol=0, atol=1e-12)
    assert np.array_equal(np.flatnonzero(np.isnan(recorded.tau[:, 1])), at_limit)
    assert not np.isnan(recorded.tau[:, [0, 2]]).any()
    assert np.allclose(np.delete(recorded.tau[:, 1], at_limit), np.delete(clipped["tau2"].to_numpy(), at_limit),
                       rtol=1e-12, atol=0)
    assert np.allclose(memory.t, table["t"].to_numpy(), rtol=0, atol=1e-12)  # the positions all kept
    assert memory.metadata["saturated_samples"] == {"tau2": at_limit.size}
    _, nothing = _caught(SaturatedTorqueWarning, lambda: read_measurements(clean, model=model))
    assert nothing == []


def test_the_streamed_reader_says_a_clipped_sensor_as_memory_finds_it(tmp_path):
    """The streamed reader (``--chunk-size``) judges a clipped sensor on the whole record block by block
    (:class:`estimation.data.log_cleaning.HeldExtremes`): the same channel, value, samples and time span as memory,
    at chunks of 250 and 251 rows (runs at the limit across a chunk's edge); its warning says that the samples are
    left out, as they are (h-streammask2). The clean record: nothing said."""
    from estimation.data import SaturatedTorqueWarning
    from estimation.data.records import read_measurements
    from estimation.streaming.chunks import read_chunks

    model, clean = _puma_record(tmp_path)
    table = pd.read_csv(clean)
    limit = 0.8 * float(np.abs(table["tau2"]).max())
    table.assign(tau2=np.clip(table["tau2"], -limit, limit)).to_csv(tmp_path / "clipped.csv", index=False,
                                                                      float_format="%.10g")
    _, said = _caught(SaturatedTorqueWarning, lambda: read_measurements(tmp_path / "clipped.csv", model=model))
    found = re.search(r"past its range: (.*), its extreme value", said[0]).group(1)
    for chunk_size in CHUNK_SIZES:
        _, streamed = _caught(SaturatedTorqueWarning, lambda size=chunk_size: list(read_chunks(
            tmp_path / "clipped.csv", model, chunk_size=size)))
        assert len(streamed) == 1 and f"past its range: {found}, its extreme value" in streamed[0], streamed
        assert "left out of the fit and of every error" in streamed[0]
    _, nothing = _caught(SaturatedTorqueWarning, lambda: list(read_chunks(clean, model, chunk_size=250)))
    assert nothing == []


def test_held_extremes_block_by_block_equal_the_whole_record():
    """:class:`HeldExtremes` fed in blocks of any size finds what it finds on the record whole: a clipped channel,
    a quantised one, one whose distinct values pass :data:`DISTINCT_SKETCH` (their count then estimated, the same
    estimate from the blocks' sketches merged, within 1 % of the true count)."""
    from estimation.data.log_cleaning import DISTINCT_SKETCH, HeldExtremes, distinct_count, value_hashes

    generator = np.random.default_rng(8)
    n = 3 * DISTINCT_SKETCH
    t = np.arange(n) / 1000.0
    q = np.column_stack([np.sin(2 * np.pi * 0.05 * t), np.cos(2 * np.pi * 0.03 * t), np.sin(2 * np.pi * 0.02 * t)])
    tau = np.column_stack([np.minimum(10 * np.sin(2 * np.pi * 0.05 * t + 0.3) + 0.1 * generator.standard_normal(n),
                                      8.0),
                           0.05 * np.round(5 * np.cos(2 * np.pi * 0.03 * t) / 0.05),
                           generator.standard_normal(n)])
    whole = HeldExtremes(3, 3, wrench=False)
    whole.add(tau, q, t)
    expected = whole.found(n)
    assert expected[:, 0].sum() > 1000 and not expected[:, 1:].any()
    for size in (997, 4096, 65537):
        blocks = HeldExtremes(3, 3, wrench=False)
        for start in range(0, n, size):
            blocks.add(tau[start:start + size], q[start:start + size], t[start:start + size])
        assert np.array_equal(blocks.found(n), expected), size
        assert blocks.described() == whole.described(), size
        assert [blocks.distinct(j) for j in range(3)] == [whole.distinct(j) for j in range(3)]
    assert abs(distinct_count(value_hashes(tau[:, 2])) / n - 1) < 0.01


def test_a_quantised_torque_channel_and_a_joint_held_against_a_hard_stop_are_not_clipped():
    from estimation.data.log_cleaning import saturated_samples

    generator = np.random.default_rng(5)
    t = np.arange(4000) / 500.0
    q = np.column_stack([0.8 * np.sin(2 * np.pi * 0.3 * t), 0.5 * np.cos(2 * np.pi * 0.2 * t)])
    tau = np.column_stack([10 * np.sin(2 * np.pi * 0.3 * t + 0.4), 5 * np.cos(2 * np.pi * 0.2 * t)])
    tau += 0.1 * generator.standard_normal(tau.shape)
    quantised = 0.05 * np.round(tau / 0.05)  # 0.05 N·m counts: every value held some ten times, the extremes too
    assert not saturated_samples(quantised, q).any()
    # joint 1 at rest against a hard stop for 1 s, its torque sensor holding its largest value (the push)
    stopped_q, stopped_tau = q.copy(), quantised.copy()
    stopped_q[1000:1500, 0] = stopped_q[999, 0]
    stopped_tau[1000:1500, 0] = quantised[:, 0].max() + 2.0
    assert not saturated_samples(stopped_tau, stopped_q).any()
    # the same channel clipped while the joint moves: found, there and only there
    clipped = quantised.copy()
    clipped[:, 0] = np.minimum(clipped[:, 0], 8.0)
    found = saturated_samples(clipped, q)
    assert np.array_equal(found[:, 0], clipped[:, 0] == 8.0) and not found[:, 1].any()


def test_a_combined_records_clipped_torque_and_wrench_are_counted_per_channel(tmp_path):
    """The combined model's record (joint torques and the base wrench): ``tau2`` and ``mz`` clipped at 80 % of their
    peaks, each named and counted, each one's samples masked in that channel only."""
    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from dynamics.simulation.synthetic import true_parameters
    from estimation.data import SaturatedTorqueWarning
    from estimation.data.records import read_measurements
    from oed.fourier import random_fourier
    from tests.test_unseen_robots import urdf_of

    model = build_model(load_robot(urdf=urdf_of("puma560:3", tmp_path)), "combined")
    t = np.arange(0.0, 4.0, 1.0 / 250.0)
    q, dq, ddq = random_fourier(model.robot, seed=4, frequency_hz=0.25).evaluate(t)
    values = model.predict(true_parameters(model, seed=0), q, dq, ddq)
    values = values + np.random.default_rng(2).standard_normal(values.shape) * 0.02 * values.std(axis=0)
    table = pd.DataFrame({"t": t, **{f"q{j + 1}": q[:, j] for j in range(3)},
                          **{name: values[:, k] for k, name in enumerate(model.channels)}})
    for name in ("tau2", "mz"):
        limit = 0.8 * float(np.abs(table[name]).max())
        table[name] = np.clip(table[name], -limit, limit)
    table.to_csv(tmp_path / "combined.csv", index=False, float_format="%.10g")
    table = pd.read_csv(tmp_path / "combined.csv")
    at = {name: np.abs(table[name]).to_numpy() >= np.abs(table[name]).max() * (1 - 1e-9) for name in ("tau2", "mz")}
    memory, said = _caught(SaturatedTorqueWarning, lambda: read_measurements(tmp_path / "combined.csv", model=model))
    assert len(said) == 1 and "range: tau2" in said[0] and "; mz at" in said[0], said
    assert memory.metadata["saturated_samples"] == {name: int(mask.sum()) for name, mask in at.items()}
    recorded = memory.as_recorded  # each clipped channel's samples masked in that channel only
    assert np.allclose(recorded.t, t, rtol=0, atol=1e-9)
    assert np.array_equal(np.isnan(recorded.tau[:, 1]), at["tau2"]) and np.array_equal(np.isnan(recorded.wrench[:, 5]),
                                                                                        at["mz"])
    assert np.count_nonzero(np.isnan(recorded.tau)) + np.count_nonzero(np.isnan(recorded.wrench)) == sum(
        int(mask.sum()) for mask in at.values())


def test_a_wrench_channel_is_clipped_while_the_robot_moves_not_at_rest_nor_when_quantised():
    """A wrench channel (a force plate's) held at its extreme while any joint moves is clipped there; the robot at
    rest with its wrench steady (every joint held) is not, nor a quantised channel."""
    from estimation.data.log_cleaning import saturated_wrench

    generator = np.random.default_rng(6)
    t = np.arange(3000) / 500.0
    q = np.column_stack([0.8 * np.sin(2 * np.pi * 0.3 * t), np.zeros(t.shape)])  # joint 2 never moves
    wrench = np.column_stack([20 * np.sin(2 * np.pi * 0.3 * t + 0.2 * k) for k in range(6)])
    wrench = 0.02 * np.round((wrench + 0.2 * generator.standard_normal(wrench.shape)) / 0.02)
    assert not saturated_wrench(wrench, q).any()
    at_rest_q, at_rest = q.copy(), wrench.copy()  # the robot at rest for 1 s, its wrench steady at a new high
    at_rest_q[1000:1500] = q[999]
    at_rest[1000:1500, 2] = wrench[:, 2].max() + 3.0
    assert not saturated_wrench(at_rest, at_rest_q).any()
    clipped = wrench.copy()
    clipped[:, 5] = np.maximum(clipped[:, 5], -15.0)
    found = saturated_wrench(clipped, q)
    assert np.array_equal(found[:, 5], clipped[:, 5] == -15.0) and not found[:, :5].any()


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.parametrize("robot", ["emps", "kuka", "panda", "tx40"])
def test_the_real_robots_logs_hold_no_read_error_and_no_clipped_torque(robot, tmp_path):
    shared_data()
    from benchmarks.bench_real_robots import ROBOTS
    from dynamics.robots import load_robot
    from estimation.data.log_cleaning import saturated_samples
    from estimation.data.records import velocity_limits
    from estimation.data.log_cleaning import encoder_glitches, position_steps
    from dynamics.models import build_model

    case = ROBOTS[robot](tmp_path)
    options = dict(zip(case.robot[::2], case.robot[1::2]))
    description = load_robot(urdf=options["--urdf"]) if "--urdf" in options else load_robot(options["--robot"])
    model = build_model(description, "internal")
    for role, record in case.records.items():
        for limit in (velocity_limits(model, description.n_joints), np.full(description.n_joints, np.inf)):
            rows, joints = encoder_glitches(position_steps(record.q, record.t, limit), limit)
            assert rows.size == 0, (role, rows[:5], joints[:5])
        assert not saturated_samples(record.tau, record.q).any(), role


@pytest.mark.slow
@pytest.mark.parametrize("verb", ["identify", "diagnose"])
def test_result_json_counts_the_clipped_samples_in_memory_and_says_streamed_that_it_did_not_look(verb, tmp_path):
    """Streamed, both verbs write memory's counts (h-cellmask20). ``result.json``'s ``saturated_samples`` (h-sensorfaults) holds the clipped samples of each record left out of
    the fit and the errors, per channel; streamed (``--chunk-size``), where the clipped channels are said but their
    samples left out as in memory (h-streammask2), it is null and ``not_computed.saturated_samples`` says why, never
    a silent null that reads as "none clipped"."""
    import json

    from oed.cli import main
    from tests.test_unseen_robots import urdf_of

    _, clean = _puma_record(tmp_path)
    _, validation = _puma_record(tmp_path, "validation.csv", seconds=2.0)
    table = pd.read_csv(clean)
    limit = 0.8 * float(np.abs(table["tau2"]).max())
    table.assign(tau2=np.clip(table["tau2"], -limit, limit)).to_csv(tmp_path / "clipped.csv", index=False,
                                                                      float_format="%.10g")
    at_limit = int(np.count_nonzero(np.abs(pd.read_csv(tmp_path / "clipped.csv")["tau2"]) >= limit * (1 - 1e-9)))
    friction = ["--friction", "viscous,coulomb,offset"] if verb == "identify" else []
    documents = {}
    for path, options in (("memory", ()), ("streamed", ("--chunk-size", "250"))):
        out = tmp_path / f"{verb}-{path}.json"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            assert main([verb, "--urdf", str(urdf_of("puma560:3", tmp_path)), "--data", str(tmp_path / "clipped.csv"),
                         "--validate", str(validation), *friction, *options, "--out", str(out)]) == 0
        documents[path] = json.loads(out.read_text())
    memory, streamed = documents["memory"], documents["streamed"]
    assert [entry["samples"] for entry in memory["saturated_samples"]["train"]] == [{"tau2": at_limit}]
    assert "validation" not in memory["saturated_samples"] and "saturated_samples" not in memory["not_computed"]
    # streamed, the files' masked cells counted as memory counts them (h-cellmask20)
    assert streamed["saturated_samples"] == memory["saturated_samples"]
    assert streamed["channel_samples"] == memory["channel_samples"] is not None
    assert "saturated_samples" not in streamed["not_computed"]


def _wrench_records(tmp_path: Path):
    """A PUMA 3's base wrench (a force plate, the external model): training 10 s, validation 4 s, test 6 s at
    250 Hz (another motion each), white noise of 2 % of each channel's spread; the positions and wrench as written."""
    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from dynamics.simulation.synthetic import true_parameters
    from oed.fourier import random_fourier
    from tests.test_unseen_robots import urdf_of

    urdf = urdf_of("puma560:3", tmp_path)
    model = build_model(load_robot(urdf=urdf), "external")
    theta = true_parameters(model, seed=0)
    generator, spread, motions = np.random.default_rng(21), None, {}
    for name, seconds, seed in (("train", 10.0, 1), ("validation", 4.0, 2), ("test", 6.0, 3)):
        t = np.arange(0.0, seconds, 1.0 / 250.0)
        q, dq, ddq = random_fourier(model.robot, seed=seed, frequency_hz=0.2).evaluate(t)
        wrench = model.predict(theta, q, dq, ddq)
        spread = wrench.std(axis=0) if spread is None else spread
        wrench = wrench + generator.standard_normal(wrench.shape) * 0.02 * spread
        pd.DataFrame({"t": t, **{f"q{j + 1}": q[:, j] for j in range(3)},
                      **{name: wrench[:, k] for k, name in enumerate(model.channels)}}).to_csv(
            tmp_path / f"{name}.csv", index=False, float_format="%.10g")
        motions[name] = (q, dq, ddq)
    return model, urdf, motions


@pytest.mark.slow
def test_a_clipped_wrench_channel_is_named_and_left_out_of_the_external_fit_and_its_errors(tmp_path, capsys):
    """A force plate's channel past its range (``mz`` clipped at 80 % of its peak in the training record): said in
    a ``SaturatedTorqueWarning``, its samples left out of the fit and the errors, ``result.json`` counting them; the
    default ``oed identify --model external`` then predicts the test record (``oed predict``) within 1.3x of a plain
    least-squares fit on the record before the fault (analytic derivatives) on every channel, at most 1.0x in total
    (allowed 2 % for the noise's sampling spread). Before (4252663, the wrench not judged): fx 1.017x, fy 1.002x,
    fz 1.032x, mx 1.297x, my 1.017x, mz 1.328x, in total 1.088x; now 1.000 to 1.002x, in total 0.999x."""
    import json

    from oed.cli import main

    model, urdf, motions = _wrench_records(tmp_path)
    table = pd.read_csv(tmp_path / "train.csv")
    limit = 0.8 * float(np.abs(table["mz"]).max())
    table.assign(mz=np.clip(table["mz"], -limit, limit)).to_csv(tmp_path / "clipped.csv", index=False,
                                                                 float_format="%.10g")
    at_limit = int(np.count_nonzero(np.abs(pd.read_csv(tmp_path / "clipped.csv")["mz"]) >= limit * (1 - 1e-9)))
    out, metrics = tmp_path / "result.json", tmp_path / "metrics.json"
    assert main(["identify", "--urdf", str(urdf), "--model", "external", "--data", str(tmp_path / "clipped.csv"),
                 "--validate", str(tmp_path / "validation.csv"), "--out", str(out)]) == 0
    said = [line for line in capsys.readouterr().err.splitlines() if "sensor past its range" in line]
    assert len(said) == 1 and "range: mz at" in said[0] and not re.search(r"; (f[xyz]|m[xy]) at", said[0]), said
    assert main(["predict", "--model", str(out), "--data", str(tmp_path / "test.csv"), "--metrics", str(metrics)]) == 0
    document = json.loads(out.read_text())
    assert [entry["samples"] for entry in document["saturated_samples"]["train"]] == [{"mz": at_limit}]
    # the plain fit: least squares on the training record before the fault, at its exact motion
    clean = pd.read_csv(tmp_path / "train.csv")
    regressor = model.evaluate_base(*motions["train"])
    theta, *_ = np.linalg.lstsq(regressor.reshape(-1, regressor.shape[2]),
                                clean[list(model.channels)].to_numpy().reshape(-1), rcond=None)
    test = pd.read_csv(tmp_path / "test.csv")[list(model.channels)].to_numpy()
    plain = np.mean((model.evaluate_base(*motions["test"]) @ theta - test) ** 2, axis=0)
    found = json.loads(metrics.read_text())
    mse = np.array([found["mse"][name] for name in model.channels])
    ratio = mse / plain
    print("test MSE over the plain fit's:", dict(zip(model.channels, ratio.round(3))),
          f"total {mse.sum() / plain.sum():.3f}")
    assert np.all(ratio <= 1.3) and mse.sum() <= 1.0 * plain.sum() * 1.02, ratio


def _clipped_and_held(tmp_path: Path, kind: str) -> Path:
    """The PUMA 3 record with ``tau2`` clipped at 80 % of its peak (``clipped``) or its torques held on two rows
    each (``held``: a drive's torques at half the positions' rate)."""
    from tests.test_logs_as_they_come import held_torques

    _, clean = _puma_record(tmp_path)
    table = pd.read_csv(clean)
    if kind == "held":
        held_torques(table, 2).to_csv(tmp_path / "held.csv", index=False, float_format="%.17g")
        return tmp_path / "held.csv"
    limit = 0.8 * float(np.abs(table["tau2"]).max())
    table.assign(tau2=np.clip(table["tau2"], -limit, limit)).to_csv(tmp_path / "clipped.csv", index=False,
                                                                      float_format="%.10g")
    return tmp_path / "clipped.csv"


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["clipped", "held"])
def test_the_streamed_identify_of_a_clipped_or_held_record_is_memorys(tmp_path, kind):
    """The streamed ``oed identify`` (``--chunk-size 250``) of a record whose torque sensor was clipped, or whose
    torques were held at half rate, gives memory's answer: the masked samples (NaN in that channel only, every row's
    positions kept) left out of the streamed sums and errors as memory leaves them out; the parameters, the
    validation and the training errors to 1e-9 relative. Before (h-sensorfaults2's strict xfail, 8322458): clipped,
    the streamed validation MSE of tau2 1.661 against memory's 0.00860 (193x; tau1 0.009469 against 0.009420, tau3
    0.005800 against 0.005794); held, the streamed reader dropped the repeats' rows (tau1 0.009542 against memory's
    0.009537, tau2 0.008447 against 0.008437)."""
    import json

    from oed.cli import main
    from tests.test_unseen_robots import urdf_of

    data = _clipped_and_held(tmp_path, kind)
    _, validation = _puma_record(tmp_path, "validation.csv", seconds=2.0)
    documents = {}
    for path, options in (("memory", ()), ("streamed", ("--chunk-size", "250"))):
        out = tmp_path / f"{path}.json"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            assert main(["identify", "--urdf", str(urdf_of("puma560:3", tmp_path)), "--data", str(data),
                         "--validate", str(validation), "--friction", "viscous,coulomb,offset", *options,
                         "--out", str(out)]) == 0
        documents[path] = json.loads(out.read_text())
    memory, streamed = documents["memory"], documents["streamed"]
    assert streamed["identification_path"] == "streamed" and memory["channel_samples"] is not None
    assert streamed["chosen"] == memory["chosen"] and streamed["channel_samples"] == memory["channel_samples"]
    assert streamed["saturated_samples"] == memory["saturated_samples"]  # counted streamed too (h-cellmask20)
    for role in ("train", "validation"):
        for channel, value in memory[role]["mse"].items():
            assert streamed[role]["mse"][channel] == pytest.approx(value, rel=1e-9), (role, channel)
    values = [[entry["value"] for entry in document["parameters"]] for document in (memory, streamed)]
    assert np.allclose(values[1], values[0], rtol=1e-9, atol=1e-9 * np.max(np.abs(values[0])))


def test_a_masked_sample_leaves_its_equation_out_of_the_sums_block_by_block():
    """:class:`~estimation.estimators.normal_equations.NormalEquations` summed block by block over a target with
    masked samples (NaN) solve the valid equations alone (``numpy.linalg.lstsq`` of them), each channel's error over
    its valid samples, the counts carried through ``+`` and ``select``; the band of the residual is taken with the
    masked residual 0 (memory's zeroed equation)."""
    from estimation.estimators.normal_equations import NormalEquations
    from estimation.estimators.summed_least_squares import SummedLeastSquares

    generator = np.random.default_rng(3)
    Y = generator.standard_normal((300, 2, 4))
    theta = np.array([1.0, -2.0, 0.5, 3.0])
    y = Y @ theta + 0.1 * generator.standard_normal((300, 2))
    y[40:90, 1] = 1e3  # a clipped stretch: its value is no measurement
    masked = y.copy()
    masked[40:90, 1] = np.nan
    sums = NormalEquations.empty(("a", "b"), ("p1", "p2", "p3", "p4"))
    for start in range(0, 300, 70):
        sums = sums.add_block(Y[start:start + 70], masked[start:start + 70])
    valid = ~np.isnan(masked)
    expected, *_ = np.linalg.lstsq(Y[valid], masked[valid], rcond=None)
    fitted = SummedLeastSquares(method="ols").fit(sums).theta_
    assert np.allclose(fitted, expected, rtol=1e-10, atol=1e-12)
    assert sums.channel_samples == (300, 250) and sums.n_equations == 550
    residual = np.where(valid, masked - Y @ fitted, 0.0)
    mse = sums.channel_mse(fitted)
    assert np.allclose([mse["a"], mse["b"]], (residual**2).sum(axis=0) / valid.sum(axis=0), rtol=1e-10)
    halves = NormalEquations.from_arrays(Y[:150], masked[:150], ("a", "b"), sums.names) + \
        NormalEquations.from_arrays(Y[150:], masked[150:], ("a", "b"), sums.names)
    assert halves.channel_samples == (300, 250) and halves.select([0, 2]).channel_samples == (300, 250)
    whole = NormalEquations.from_arrays(Y, y, ("a", "b"), sums.names)  # nothing masked: no counts carried
    assert whole.channel_samples is None and np.allclose(whole.samples, 300)


def test_the_streamed_reader_masks_the_cells_memory_masks(tmp_path):
    """Chunk by chunk (of 97 rows: the clip across their edges), the streamed reader gives memory's
    samples: a clipped sensor's samples NaN in that channel only, a held channel's repeats NaN with every row's
    positions kept (``tests/test_logs_as_they_come.py``); the errors at the recorded samples
    (:func:`~estimation.streaming.chunks.logged_chunks`) alike. A jittered clipped record: masked before the
    resampling, the grid's torques memory's."""
    from estimation.data.records import read_measurements
    from estimation.streaming.chunks import logged_chunks, read_chunks

    model, _ = _puma_record(tmp_path)
    clipped = _clipped_and_held(tmp_path, "clipped")
    jittered = pd.read_csv(clipped)
    jittered["t"] += np.random.default_rng(1).uniform(-0.3, 0.3, len(jittered)) * 0.004
    jittered.to_csv(tmp_path / "jittered.csv", index=False, float_format="%.17g")
    for kind, data, size in (("clipped", clipped, 97), ("jittered", tmp_path / "jittered.csv", 250)):  # held:
        with warnings.catch_warnings():  # tests/test_logs_as_they_come.py
            warnings.simplefilter("ignore")
            memory = read_measurements(data, model=model)
            chunks = list(read_chunks(data, model, chunk_size=size))
            logged = list(logged_chunks(data, model, chunk_size=size))
        assert np.isnan(memory.tau).any(), kind
        assert np.allclose(np.vstack([chunk.q for chunk in chunks]), memory.q, rtol=0, atol=1e-12), kind
        assert np.allclose(np.vstack([chunk.tau for chunk in chunks]), memory.tau, rtol=0, atol=1e-12,
                           equal_nan=True), kind
        assert np.array_equal(np.vstack([chunk.tau for chunk in logged]), memory.as_recorded.tau, equal_nan=True), kind


def test_the_streamed_counts_of_masked_cells_are_memorys(tmp_path):
    """``result.json``'s ``saturated_samples`` and ``channel_samples`` of a streamed run
    (:func:`~estimation.streaming.masked_counts.streamed_mask_counts`, h-cellmask20) hold memory's counts: the
    clipped sensor's samples (memory's ``metadata["saturated_samples"]``) and each channel's valid samples of the
    record as recorded (memory's ``channel_counts``), on a clipped, a jittered clipped and a held record; a clean
    record: ``None`` for both, as memory writes; a clipped file with a hole: its segments' counts, as memory's
    segments hold them."""
    from estimation.data.channel_mask import channel_counts
    from estimation.data.records import read_measurements, read_record
    from estimation.streaming.masked_counts import streamed_mask_counts

    model, clean = _puma_record(tmp_path)
    clipped = _clipped_and_held(tmp_path, "clipped")
    held = _clipped_and_held(tmp_path, "held")
    jittered = pd.read_csv(clipped)
    jittered["t"] += np.random.default_rng(1).uniform(-0.3, 0.3, len(jittered)) * 0.004
    jittered.to_csv(tmp_path / "jittered.csv", index=False, float_format="%.17g")
    for data in (clipped, tmp_path / "jittered.csv", held):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            memory = read_measurements(data, model=model)
        recorded = memory.as_recorded
        counts = channel_counts(recorded.tau)
        saturated, channels = streamed_mask_counts({"train": [data]}, model, chunk_size=97)
        expected = memory.metadata.get("saturated_samples")
        assert (None if saturated is None else saturated["train"][0]["samples"]) == (
            dict(expected) if expected else None), data.name
        assert channels == {"train": {"samples": int(recorded.n_samples), "channels": {
            f"tau{j + 1}": int(count) for j, count in enumerate(counts)}}}, data.name
    assert streamed_mask_counts({"train": [clean], "validation": [clean]}, model, chunk_size=97) == (None, None)
    holed = pd.read_csv(clipped)  # a hole of 5 s: memory reads two segments, each with its clipped samples
    holed.loc[400:, "t"] += 5.0
    holed.to_csv(tmp_path / "holed.csv", index=False, float_format="%.17g")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        segments = read_record(tmp_path / "holed.csv", model=model)
    saturated, _ = streamed_mask_counts({"train": [str(tmp_path / "holed.csv")]}, model, chunk_size=97)
    assert [(entry["segment"], entry["samples"]) for entry in saturated["train"]] == [
        (segment.metadata.get("segment", 1), dict(segment.metadata["saturated_samples"])) for segment in segments]


def test_a_quantised_peak_is_kept_and_a_clip_of_the_same_channel_caught_whole_and_in_blocks():
    """A coarsely quantised torque (0.01 N·m steps at 1 kHz) holds its smooth peak some 90 samples, ten times as
    often as its other levels: no clipped sensor, since the samples on both sides step away by whole quanta and their
    trend stays within a quantum of the hold (:func:`estimation.data.log_cleaning.quantised_peak`); the same channel
    cut ten quanta below its peak is clipped there and only there. Block by block as on the record whole (the
    streamed reader's scan), the peak cut across blocks."""
    from estimation.data.log_cleaning import HeldExtremes, saturated_samples

    t = np.arange(3000) / 1000.0
    q = np.column_stack([np.sin(2 * np.pi * 0.5 * t), 0.5 * np.cos(2 * np.pi * 0.3 * t)])
    tau = np.round((2.0 * q + 0.3) / 1e-2) * 1e-2
    peak = np.flatnonzero(tau[:, 0] == tau[:, 0].max())
    assert peak.size > 80  # held ~90 samples: past the frequency rule alone (SATURATION_FACTOR)
    assert not saturated_samples(tau, q).any()
    clipped = tau.copy()
    clipped[:, 0] = np.minimum(clipped[:, 0], tau[:, 0].max() - 0.1)
    found = saturated_samples(clipped, q)
    assert np.array_equal(found[:, 0], clipped[:, 0] == clipped[:, 0].max()) and not found[:, 1].any()
    for values in (tau, clipped):
        whole = saturated_samples(values, q)
        for size in (7, 45, 997):
            blocks = HeldExtremes(2, 2, wrench=False)
            for start in range(0, t.size, size):
                blocks.add(values[start:start + size], q[start:start + size])
            assert np.array_equal(blocks.found(t.size), whole), size


def test_the_streamed_difference_floor_of_a_masked_channel_is_memorys():
    """The noise floor by passes (:func:`estimation.streaming.record_floor.difference_floor`, blocks of 61 rows, a
    capacity of 50 values: the medians found by histogram passes) of channels with masked samples (a clipped
    stretch on two channels, single samples on a third) equals memory's :func:`~estimation.uncertainty.noise_floor.
    difference_variance` (each channel's valid differences, the fewest channel's degrees of freedom); before
    (8322458) it refused the NaN ("the channels hold NaN or inf")."""
    from estimation.streaming.record_floor import difference_floor
    from estimation.uncertainty.noise_floor import difference_variance

    generator = np.random.default_rng(5)
    values = generator.standard_normal((900, 3)) * [0.1, 0.2, 0.05]
    values[300:420, 1] = np.nan
    values[600:650, 2] = np.nan
    values[[100, 140, 777], 0] = np.nan

    def blocks():
        for start in range(0, values.shape[0], 61):
            yield values[start:start + 61]

    variance, dof = difference_variance(values)
    floor = difference_floor(blocks, ("tau1", "tau2", "tau3"), capacity=50)
    assert np.allclose(floor.variance, variance, rtol=1e-12, atol=0)
    assert floor.dof == pytest.approx(dof)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="the diagnosis's search takes whole rows (estimation.data.channel_mask."
                   "whole_rows): a clipped tau2 leaves 205 of 750 rows out of the search for every channel; measured "
                   "at h-cellmask20: the chosen model's validation MSE 1.205x, 1.069x, 1.005x the plain law's "
                   "fitted per cell (benchmarks/README.md, h-cellmask20)")
def test_a_clipped_channel_costs_the_diagnosis_no_more_than_its_own_samples(tmp_path):
    """The default ``oed diagnose`` of a PUMA 3 record whose tau2 is clipped at 80 % of its peak (205 of 750
    samples masked in tau2 only) predicts the validation record (another motion) per channel within 5 % of the
    truth's friction law (viscous, Coulomb and offset on every joint) fitted per cell by ``oed identify``: what a
    search that masks per cell would reach. Measured (h-cellmask20): the diagnosis names ``coulomb:tanh`` on tau1
    and no offset on tau2 from the 545 whole rows it searches (the clean record: ``coulomb`` on tau1 and the offset
    on tau2 completed), validation tau1 0.01240 against 0.01029, tau2 0.01304 against 0.01220, tau3 0.003943
    against 0.003922."""
    import json

    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from oed.cli import main
    from tests.test_unseen_robots import FRICTION, truth, urdf_of, write_record

    urdf = urdf_of("puma560:3", tmp_path)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    _, spread = write_record(model, truth(model), Log(3.0, 250.0, velocity=False), 11, tmp_path / "clean.csv")
    write_record(model, truth(model), Log(2.0, 250.0, velocity=False), 12, tmp_path / "validation.csv", spread)
    table = pd.read_csv(tmp_path / "clean.csv")
    limit = 0.8 * float(np.abs(table["tau2"]).max())
    table.assign(tau2=np.clip(table["tau2"], -limit, limit)).to_csv(tmp_path / "clipped.csv", index=False,
                                                                      float_format="%.10g")
    errors = {}
    for verb, options in (("diagnose", ()), ("identify", ("--friction", FRICTION))):
        out = tmp_path / f"{verb}.json"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            assert main([verb, "--urdf", str(urdf), "--data", str(tmp_path / "clipped.csv"), "--validate",
                         str(tmp_path / "validation.csv"), *options, "--out", str(out)]) == 0
        document = json.loads(out.read_text())
        assert document["channel_samples"]["train"]["channels"]["tau2"] < 750, verb
        errors[verb] = document["model_file"]["reported"]["validation_mse"]
    ratios = {name: errors["diagnose"][name] / errors["identify"][name] for name in errors["identify"]}
    print("the diagnosis's validation MSE over the plain law's fitted per cell:", ratios)
    assert all(ratio <= 1.05 for ratio in ratios.values()), ratios
