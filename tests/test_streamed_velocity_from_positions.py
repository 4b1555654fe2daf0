"""Records that log ``dq`` but not ``ddq``: memory's derivative choice offers each filter twice, on the logged
velocity and with ``dq`` made from the positions (``Preprocessing.velocity_from_positions``); the streamed choice
offered the first only, so on short records (4 s at 0.5 Hz, the filter path) it chose another filter and its
parameters were 3e-3 from memory's (benchmarks/README.md, h-streamfloor). Now the streamed choice is memory's, and a
source read "with the velocity from the positions" (``estimation.streaming.chunks.positions_source``) is read
without its logged ``dq``, so every pass derives ``dq`` as memory's filter does.

- cheap: a positions source reads the same chunks without ``dq``; the filter on them is memory's plan bit for bit;
- slow: ``oed identify`` on the 4-s records, memory against ``--chunk-size 400``: the same plan (17 Hz, ``dq`` from
  the positions), parameters and validation errors to 1e-10; the streamed ``oed predict`` of the model file gives
  memory's test errors.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from estimation.streaming.chunks import from_positions, positions_source, read_chunks, source_file

#: streamed against memory: the same samples, sums in another order
SAME = 1e-10


def _simulated(folder, *, joints=None, frequency_hz=0.5, roles=(("train", 1), ("validate", 2), ("test", 3))):
    """PUMA records of two periods at 200 Hz logging ``t, q, dq, tau`` (no ``ddq``)."""
    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from dynamics.simulation.synthetic import simulate
    from oed.fourier import random_fourier

    robot = load_robot("puma560") if joints is None else load_robot("puma560", joints=joints)
    model = build_model(robot, "internal", "viscous")
    theta = model.nominal_parameters(viscous=[4.0, 4.0, 3.0, 1.0, 1.0, 1.0][:model.robot.n_joints])
    files = {}
    for role, seed in roles:
        trajectory = random_fourier(model.robot, seed=seed, frequency_hz=frequency_hz)
        clean = simulate(model, theta, trajectory, rate_hz=200.0)
        noise = {f"tau{j + 1}": 0.02 * span for j, span in enumerate(np.ptp(clean.tau, axis=0))}
        frame = simulate(model, theta, trajectory, rate_hz=200.0, periods=2, noise=noise, seed=10 + seed).to_frame()
        frame = frame[[column for column in frame.columns if not column.startswith("ddq")]]
        files[role] = folder / f"{role}.csv"
        frame.to_csv(files[role], index=False, float_format="%.12g")
    return model, files


def test_a_positions_source_is_read_without_its_logged_velocities_and_filtered_as_memory(tmp_path):
    from estimation.data.records import read_record
    from estimation.preprocessing.plan import Preprocessing, prepare
    from estimation.streaming.chunks import preprocessed_chunks

    model, files = _simulated(tmp_path, joints=2, roles=(("train", 1),))
    path = files["train"]
    source = positions_source(str(path))
    assert from_positions(source) and not from_positions(path) and source_file(source) == (path, None)
    plain, without = list(read_chunks(path, model, chunk_size=300)), list(read_chunks(source, model, chunk_size=300))
    assert [chunk.n_samples for chunk in plain] == [chunk.n_samples for chunk in without]
    for chunk, other in zip(plain, without):
        assert chunk.dq is not None and other.dq is None and other.ddq is None
        assert np.array_equal(chunk.q, other.q) and np.array_equal(chunk.tau, other.tau)
    # memory's plan with dq from the positions, and the streamed filter on the source read without dq
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        record = read_record(path, model=model)[0]
        plan = Preprocessing("butterworth", cutoff_hz=17.0, order=4, velocity_from_positions=True)
        memory = prepare([record], plan)
        streamed = list(preprocessed_chunks(source, model, chunk_size=300, cutoff_hz=17.0))
    dq = np.concatenate([chunk.dq for chunk in streamed])
    logged = np.concatenate([chunk.dq for chunk in preprocessed_chunks(path, model, chunk_size=300, cutoff_hz=17.0)])
    assert dq.shape == memory.dq.shape
    np.testing.assert_allclose(dq, memory.dq, rtol=0.0, atol=1e-12 * np.max(np.abs(memory.dq)))
    assert np.max(np.abs(logged - memory.dq)) > 1e-6 * np.max(np.abs(memory.dq))  # the logged one is another dq


@pytest.mark.slow  # oed identify on a 6-joint arm in memory and streamed, two predictions (about 3 min under load)
def test_identify_streamed_on_short_records_logging_velocities_is_memory_s(tmp_path):
    from oed.cli import main

    _, files = _simulated(tmp_path)
    results, tests = {}, {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name, extra in (("memory", []), ("streamed", ["--chunk-size", "400"])):
            out = tmp_path / f"{name}.json"
            assert main(["identify", "--robot", "puma560", "--friction", "viscous", "--data", str(files["train"]),
                         "--validate", str(files["validate"]), "--out", str(out), "--quiet", *extra]) == 0
            results[name] = json.loads(out.read_text())
            metrics = tmp_path / f"{name}-test.json"
            assert main(["predict", "--model", str(out), "--data", str(files["test"]), "--metrics", str(metrics),
                         *extra]) == 0
            tests[name] = json.loads(metrics.read_text())
    memory, streamed = results["memory"], results["streamed"]
    for key in ("method", "cutoff_hz", "velocity_from_positions"):
        assert streamed["preprocessing"][key] == memory["preprocessing"][key], key
    assert memory["preprocessing"]["velocity_from_positions"] is True  # the case: dq from the positions chosen
    assert streamed["model_file"]["preprocessing"].get("velocity_from_positions") is True
    mine, theirs = np.array(memory["model_file"]["theta"]), np.array(streamed["model_file"]["theta"])
    assert np.max(np.abs(mine - theirs)) <= SAME * np.max(np.abs(mine))
    assert tests["streamed"]["prediction_path"] == "streamed"
    for channel, value in memory["validation"]["mse"].items():
        assert streamed["validation"]["mse"][channel] == pytest.approx(value, rel=1e-9), channel
        assert tests["streamed"]["mse"][channel] == pytest.approx(tests["memory"]["mse"][channel], rel=1e-9), channel
