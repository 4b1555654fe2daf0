"""``oed simulate``: round trip to the measurement format, truth record, reproducibility, bad input."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from oed.cli import main
from oed.fourier import FourierTrajectory


@pytest.fixture
def trajectory_file(tmp_path):
    generator = np.random.default_rng(4)
    path = tmp_path / "traj.json"
    FourierTrajectory(0.5, np.zeros(3), generator.uniform(-0.15, 0.15, (3, 3)), generator.uniform(-0.15, 0.15, (3, 3))).save(path)
    return path


def _simulate(trajectory_file, out, *extra):
    return main(["simulate", "--robot", "puma560", "--joints", "3", "--trajectory", str(trajectory_file),
                 "--out", str(out), *extra])


def test_simulate_writes_positions_torques_and_wrench(tmp_path, trajectory_file, capsys):
    out, truth = tmp_path / "data.csv", tmp_path / "truth.json"
    assert _simulate(trajectory_file, out, "--effects", "coulomb,plate_moment", "--seed", "3", "--truth", str(truth)) == 0
    frame = pd.read_csv(out)
    expected = ["t", "q1", "q2", "q3", "tau1", "tau2", "tau3", "fx", "fy", "fz", "mx", "my", "mz"]
    assert list(frame.columns) == expected and len(frame) == 2000
    np.testing.assert_allclose(np.diff(frame["t"]), 1e-3, atol=1e-9)
    record = json.loads(truth.read_text())
    assert record["seed"] == 3 and [effect["name"] for effect in record["effects"]] == ["viscous", "coulomb", "plate_moment"]
    assert record["true_parameters"]["fv1"] == pytest.approx(5.80, abs=0.01)
    assert record["true_parameters"]["mz_off"] == 2.0
    # the PUMA is ~22 kg of links 2-3 (Armstrong): the plate carries its weight on average
    robot = load_robot("puma560", joints=3)
    weight = sum(joint.inertial[0] for joint in robot.joints) * 9.81
    assert frame["fz"].mean() == pytest.approx(weight, rel=0.02)
    assert "wrote" in capsys.readouterr().out


def test_simulated_file_identifies_the_true_parameters(tmp_path, trajectory_file):
    """Round trip: the written torques, with the written true derivatives, fit the model exactly."""
    out = tmp_path / "data.parquet"
    assert _simulate(trajectory_file, out, "--with-derivatives", "--noise-tau", "0", "--q-resolution", "none",
                     "--effects", "offset", "--truth", str(tmp_path / "truth.json")) == 0
    frame = pd.read_parquet(out)
    columns = lambda prefix: frame[[f"{prefix}{j}" for j in (1, 2, 3)]].to_numpy()  # noqa: E731
    model = build_model(load_robot("puma560", joints=3), "internal", ("viscous", "offset"))
    named = json.loads((tmp_path / "truth.json").read_text())["true_parameters"]
    theta = np.array([named.get(name, 0.0) for name in model.parameter_names])
    predicted = model.predict(theta, columns("q"), columns("dq"), columns("ddq"))
    np.testing.assert_allclose(predicted, columns("tau"), atol=1e-6)


def test_same_seed_same_file_other_seed_other_noise(tmp_path, trajectory_file):
    paths = [tmp_path / name for name in ("a.csv", "b.csv", "c.csv")]
    for path, seed in zip(paths, ("1", "1", "2")):
        assert _simulate(trajectory_file, path, "--seed", seed) == 0
    assert paths[0].read_bytes() == paths[1].read_bytes()
    assert paths[0].read_bytes() != paths[2].read_bytes()


def test_computed_torque_controller_tracks_closely(tmp_path, trajectory_file, capsys):
    out = tmp_path / "data.csv"
    assert _simulate(trajectory_file, out, "--controller", "computed-torque", "--q-resolution", "1e-3") == 0
    q = pd.read_csv(out)[["q1", "q2", "q3"]].to_numpy()
    np.testing.assert_allclose(q / 1e-3, np.round(q / 1e-3), atol=1e-6)  # the asked resolution
    t, q_d, _, _ = FourierTrajectory.load(trajectory_file).sample(1000)
    assert np.abs(q - q_d).max() < 1e-3


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["--joints", "4"], "has 3 joints, the robot puma560[4] has 4"),
        (["--effects", "magnets"], "unknown effect 'magnets'"),
        (["--effect-values", '{"coulomb": [1, 2]}', "--effects", "coulomb"], "one value or 3"),
        (["--effect-values", "missing.json"], "neither JSON text nor an existing file"),
        (["--effect-values", "{not json"], "not valid JSON"),
        (["--noise-wrench", "1", "2"], "one value or six"),
        (["--q-resolution", "fine"], "--q-resolution"),
        (["--periods", "0"], "periods"),
        (["--effect-values", '{"coulomb": "strong"}', "--effects", "coulomb"], "effect 'coulomb': bad values 'strong'"),
    ],
)
def test_bad_input_exits_2_without_output(tmp_path, trajectory_file, capsys, arguments, message):
    out = tmp_path / "data.csv"
    assert _simulate(trajectory_file, out, *arguments) == 2
    assert message in capsys.readouterr().err
    assert not out.exists() and list(tmp_path.iterdir()) == [trajectory_file]


def test_missing_trajectory_and_bad_output_suffix(tmp_path, trajectory_file, capsys):
    assert _simulate(tmp_path / "nope.json", tmp_path / "data.csv") == 2
    assert "trajectory file not found" in capsys.readouterr().err
    assert _simulate(trajectory_file, tmp_path / "data.txt") == 2
    assert ".csv or .parquet" in capsys.readouterr().err
    assert not (tmp_path / "data.csv").exists() and not (tmp_path / "data.txt").exists()


@pytest.mark.parametrize(
    ("document", "message"),
    [
        ("[1, 2]", "a trajectory document is a JSON object"),
        ("5", "a trajectory document is a JSON object"),
        ('{"frequency_hz": 0.2, "q0": [0, 0, 0], "a": [[0, 1], [0], [0]], "b": [[0], [0], [0]]}',
         "Fourier coefficients a must be numbers in a regular"),
        ('{"frequency_hz": "fast", "q0": [0, 0, 0], "a": [[0], [0], [0]], "b": [[0], [0], [0]]}',
         "frequency_hz must be a number, got 'fast'"),
    ],
)
def test_malformed_trajectory_documents_are_named(tmp_path, capsys, document, message):
    path = tmp_path / "traj.json"
    path.write_text(document)
    assert _simulate(path, tmp_path / "data.csv") == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "data.csv").exists()


def test_held_torques_remove_the_half_sample_bias_of_derivatives_from_positions(tmp_path):
    """The simulator holds each torque over a sample; a Fourier fit of the positions sees it half a
    sample late. Without ``--held-torques`` the estimates miss the truth by many standard
    deviations; with it, the base parameters are back within a few."""
    generator = np.random.default_rng(8)
    trajectory_file, data, truth = tmp_path / "traj.json", tmp_path / "data.csv", tmp_path / "truth.json"
    FourierTrajectory(0.5, np.zeros(3), generator.uniform(-0.5, 0.5, (3, 3)), generator.uniform(-0.5, 0.5, (3, 3))).save(trajectory_file)
    assert _simulate(trajectory_file, data, "--periods", "4", "--warmup-periods", "1", "--seed", "5",
                     "--truth", str(truth)) == 0
    model = build_model(load_robot("puma560", joints=3), "internal", "viscous")
    named = json.loads(truth.read_text())["true_parameters"]
    true_base = model.base.to_base(np.array([named.get(name, 0.0) for name in model.parameter_names]))
    largest = {}
    for flag in ((), ("--held-torques",)):
        out = tmp_path / f"result{len(flag)}.json"
        assert main(["identify", "--robot", "puma560", "--joints", "3", "--model", "internal", "--friction", "viscous",
                     "--data", str(data), "--frequency", "0.5", "--harmonics", "15", *flag, "--out", str(out)]) == 0
        parameters = json.loads(out.read_text())["parameters"]
        values, std = (np.array([p[key] for p in parameters]) for key in ("value", "std"))
        largest[flag] = np.max(np.abs(values - true_base) / std)
    # measured: 8.3 and 1.9 standard deviations
    assert largest[()] > 6 and largest[("--held-torques",)] < 4, largest


def test_a_trajectory_designed_for_another_robot_is_flagged(tmp_path, capsys):
    path = tmp_path / "other.json"
    FourierTrajectory(0.5, np.zeros(3), np.full((3, 2), 0.05), np.zeros((3, 2)), metadata={"robot": "emps"}).save(path)
    assert _simulate(path, tmp_path / "data.csv") == 0
    assert "was designed for emps, and is played on puma560[3]" in capsys.readouterr().err
