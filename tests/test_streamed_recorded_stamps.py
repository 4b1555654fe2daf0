"""A streamed run's errors on a jittered validation log, at the recorded samples, block by block: the figures of the
whole read (what ``oed predict`` measures) to 1e-9, whatever the block, on a log whose re-sent rows the loader drops
too."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.simulator import Simulator
from estimation.identification.model_file import RobotSource, summed_model_file_document
from estimation.streaming.recorded_errors import streamed_errors_at_stamps, streamed_plan
from oed.cli import main
from oed.fourier import random_fourier
from oed.workflows.model_files import recorded_validation_errors
from tests.test_recorded_stamps import logger_faults

EFFECTS = "viscous,coulomb,offset"


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """Positions and torques of a 3-joint PUMA at 200 Hz: a training log, and validation logs of another motion with
    stamps jittered by up to ±30 % of a step and an 8 ms stall (``jittered``), and as a logger with re-sent rows
    writes it too (``resent``)."""
    folder = tmp_path_factory.mktemp("streamed_stamps")
    robot = load_robot("puma560", joints=3)
    simulator = Simulator(robot, rate_hz=200.0)
    paths = {}
    for name, seed in (("train", 1), ("jittered", 2), ("resent", 2)):
        frame = simulator.run(random_fourier(robot, seed, frequency_hz=0.1), duration=8.0, warmup_periods=1,
                              seed=seed).measurements.to_frame()
        frame = frame[[column for column in frame.columns if not column.startswith(("dq", "ddq"))]]
        if name == "jittered":
            generator = np.random.default_rng(seed)
            step = float(np.median(np.diff(frame.t)))
            frame["t"] = frame.t + generator.uniform(-0.3, 0.3, len(frame)) * step
            frame = frame.drop(index=range(900, 908)).reset_index(drop=True)
        elif name == "resent":
            frame = logger_faults(frame, seed)
        paths[name] = folder / f"{name}.csv"
        frame.to_csv(paths[name], index=False, float_format="%.10g")
    return robot, paths


@pytest.mark.parametrize("chunk_size", [250, 1000, 100_000])
def test_block_by_block_at_the_recorded_samples_is_the_whole_read(logs, chunk_size):
    robot, paths = logs
    model = build_model(robot, "internal", EFFECTS)
    thetas = {"nominal": model.base.K @ model.nominal_parameters(),
              "other": np.random.default_rng(0).normal(size=model.n_base)}
    document = summed_model_file_document(
        model, type("Estimate", (), {"method": "ols", "names": model.base.names, "values": thetas["nominal"],
                                     "cov": np.eye(model.n_base), "channel_variance": np.ones(3),
                                     "weights": np.ones(3)}),
        robot=RobotSource.from_description(robot, builtin="puma560", urdf=None, joints=3),
        preprocessing=streamed_plan(paths["jittered"], model, cutoff_hz=6.0, chunk_size=chunk_size))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the logs' findings
        blocks = streamed_errors_at_stamps(model, thetas, [paths["jittered"]], chunk_size=chunk_size, cutoff_hz=6.0)
        whole = recorded_validation_errors(document, thetas, [paths["jittered"]])
        # the re-sent rows dropped block by block as the loader drops them (the same grid): the whole read's figures
        resent = streamed_errors_at_stamps(model, thetas, [paths["resent"]], chunk_size=chunk_size, cutoff_hz=6.0)
        resent_whole = recorded_validation_errors(document, thetas, [paths["resent"]])
    for name in thetas:
        assert resent[name] == pytest.approx(resent_whole[name], rel=1e-9)
    assert whole is not None and set(blocks) == set(thetas)
    for name in thetas:
        assert blocks[name] == pytest.approx(whole[name], rel=1e-9)


def test_streamed_identify_on_a_jittered_log_reports_what_predict_measures(logs, tmp_path):
    """The streamed answer's validation error and every candidate's, on the jittered log, block by block: ``oed
    predict`` reproduces the chosen model's, and the in-memory run gives the same figures."""
    _, paths = logs
    documents = {}
    for name, options in (("memory", ()), ("streamed", ("--memory-budget", "1KB"))):
        out = tmp_path / f"{name}.json"
        assert main(["identify", "--joints", "3", "--friction", EFFECTS, "--data", str(paths["train"]), "--validate",
                     str(paths["jittered"]), "--cutoff", "6", "--out", str(out), "--quiet", *options]) == 0
        documents[name] = json.loads(out.read_text())
    memory, streamed = documents["memory"], documents["streamed"]
    assert streamed["identification_path"] == "streamed"
    assert streamed["streaming"]["validation_files"][0]["resampled_from"] is not None
    assert streamed["chosen"] == memory["chosen"]
    candidates = {name: {c["name"]: c["validation_mse"] for c in document["model_selection"]["candidates"]}
                  for name, document in documents.items()}
    for name, mse in candidates["memory"].items():
        assert candidates["streamed"][name] == pytest.approx(mse, rel=1e-6)
    metrics = tmp_path / "metrics.json"
    assert main(["predict", "--model", str(tmp_path / "streamed.json"), "--data", str(paths["jittered"]),
                 "--metrics", str(metrics)]) == 0
    assert json.loads(metrics.read_text())["mse"] == pytest.approx(streamed["validation"]["mse"], rel=1e-6)
