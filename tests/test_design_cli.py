"""``oed design``: outputs, bad input (clear error, exit code 2, no half-written files)."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from dynamics.robots import load_robot
from oed.bounds import InfeasibleBoundsError, JointBounds
from oed.cli import main
from oed.excitation import DesignError, DesignSettings, design_excitation


def test_cli_writes_json_csv_and_figure(tmp_path):
    out, csv, png = tmp_path / "traj.json", tmp_path / "traj.csv", tmp_path / "traj.png"
    code = main(["design", "--robot", "puma560", "--joints", "3", "--model", "internal", "--starts", "1",
                 "--seed", "2", "--out", str(out), "--csv", str(csv), "--plot", str(png), "--quiet"])
    assert code == 0
    document = json.loads(out.read_text())
    for key in ("frequency_hz", "harmonics", "q0", "a", "b", "joint_names", "model", "criterion", "cost", "cond",
                "bounds", "solver"):
        assert key in document
    assert np.shape(document["a"]) == (3, 5) and document["frequency_hz"] == 0.2
    table = np.loadtxt(csv, delimiter=",", skiprows=1)
    assert table.shape == (5000, 10)
    assert csv.read_text().splitlines()[0] == "t,q1,q2,q3,dq1,dq2,dq3,ddq1,ddq2,ddq3"
    assert png.stat().st_size > 1000


def test_impossible_bounds_file_fails_cleanly(tmp_path, capsys):
    bounds = tmp_path / "bounds.json"
    bounds.write_text(json.dumps({"q_min": [0, 0, 0], "q_max": [1, -1, 1], "dq_max": [1, 1, 1], "ddq_max": [1, 1, 1]}))
    out = tmp_path / "traj.json"
    code = main(["design", "--joints", "3", "--bounds", str(bounds), "--out", str(out), "--quiet"])
    assert code == 2
    assert "joint2" in capsys.readouterr().err
    assert not out.exists() and list(tmp_path.iterdir()) == [bounds]


def test_non_positive_frequency_fails_cleanly(tmp_path, capsys):
    out = tmp_path / "traj.json"
    assert main(["design", "--joints", "3", "--frequency", "0", "--out", str(out), "--quiet"]) == 2
    assert "frequency" in capsys.readouterr().err
    assert not out.exists()


def test_solver_failure_names_the_status(tmp_path, capsys):
    out = tmp_path / "traj.json"
    code = main(["design", "--joints", "3", "--model", "internal", "--max-iter", "2", "--starts", "2",
                 "--out", str(out), "--quiet"])
    assert code == 2
    assert "Maximum_Iterations_Exceeded" in capsys.readouterr().err
    assert not out.exists()


def test_zero_velocity_bound_is_infeasible():
    with pytest.raises(InfeasibleBoundsError, match="dq_max"):
        JointBounds.symmetric([1, 1], [1, 0], [1, 1])


def test_urdf_bounds_need_accelerations(prismatic_urdf):
    robot = load_robot(urdf=prismatic_urdf)
    with pytest.raises(ValueError, match="ddq_max"):
        JointBounds.from_robot(robot)


def test_bounds_for_another_joint_count_are_rejected():
    robot = load_robot("puma560", joints=3)
    with pytest.raises(ValueError, match="2 joints"):
        design_excitation(robot, bounds=JointBounds.symmetric([1, 1], [1, 1], [1, 1]), starts=1)


def test_design_error_is_a_runtime_error():
    robot = load_robot("puma560", joints=3)
    with pytest.raises(DesignError, match="start 0"):
        design_excitation(robot, model="internal", starts=1, settings=DesignSettings(max_iter=1))


@pytest.mark.parametrize(
    "bounds,message",
    [
        ({"q_max": [1, 1e-9, 1], "dq_max": [1, 1, 1], "ddq_max": [1, 1, 1]}, r"joint 'joint2': position range \[-1e-09, 1e-09\] is too narrow"),
        ({"q_max": [1, 1, 1], "dq_max": [1, 1, 1e-9], "ddq_max": [1, 1, 1]}, "joint 'joint3': velocity bound dq_max = 1e-09 is too narrow"),
    ],
)
def test_bounds_too_narrow_for_the_optimiser_name_joint_and_bound(tmp_path, capsys, bounds, message):
    """Such bounds used to reach IPOPT and end in CasADi's 'Ill-posed problem detected: LBG[k] <= UBG[k]'."""
    path, out = tmp_path / "bounds.json", tmp_path / "traj.json"
    path.write_text(json.dumps(bounds))
    code = main(["design", "--joints", "3", "--model", "internal", "--bounds", str(path), "--out", str(out), "--quiet"])
    assert code == 2
    error = capsys.readouterr().err
    assert re.search(message, error) and "LBG" not in error
    assert not out.exists()


def test_urdf_robot_without_bounds_is_told_the_cli_options(tmp_path, capsys, prismatic_urdf):
    out = tmp_path / "traj.json"
    assert main(["design", "--urdf", str(prismatic_urdf), "--model", "internal", "--out", str(out), "--quiet"]) == 2
    error = capsys.readouterr().err
    assert "--bounds FILE" in error and "--ddq-max" in error
    assert not out.exists()


def test_negative_workers_are_named(tmp_path, capsys):
    """--workers -1 used to run the starts in turn silently."""
    out = tmp_path / "traj.json"
    assert main(["design", "--joints", "3", "--model", "internal", "--workers", "-1", "--out", str(out), "--quiet"]) == 2
    assert "--workers must be 0" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("verb", [["design", "--joints", "3"], ["simulate", "--trajectory", "t.json"], ["aprbs"],
                                  ["servo-simulate", "--aprbs", "a.csv"]])
def test_negative_seed_is_an_argument_error_naming_the_option(tmp_path, capsys, verb):
    """numpy's 'expected non-negative integer' (exit 2 after the work had started) did not say which option."""
    out = tmp_path / "out.csv"
    with pytest.raises(SystemExit) as exit_info:
        main([*verb, "--seed", "-1", "--out", str(out)])
    assert exit_info.value.code == 2
    assert "argument --seed: must be a non-negative integer, got -1" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize(
    "settings,message",
    [
        (dict(cost_samples=1), "cost_samples = 1 cannot resolve 5 harmonics"),
        (dict(frequency_hz=1e-9), "more than the 1e.07 checked at most"),  # was a MemoryError of 7 TiB
    ],
)
def test_settings_that_cannot_work_are_refused_up_front(settings, message):
    with pytest.raises(ValueError, match=message):
        DesignSettings(**settings)


def test_an_aprbs_too_long_to_hold_is_refused():
    from oed.aprbs_signal import APRBSDesign

    with pytest.raises(ValueError, match="1e.09 samples, more than 1e.07"):
        APRBSDesign(duration=1e7, dt=0.01)


@pytest.mark.parametrize(
    "document,error,message",
    [
        ({"q_max": [True, 1, 1], "dq_max": [1, 1, 1], "ddq_max": [5, 5, 5]}, TypeError, "q_max must be a sequence of numbers"),
        ({"q_max": [1, 1, 1], "dq_max": [1, 1, 1], "ddq_max": [5, 5, 5], "joint_names": "abc"}, TypeError,
         "joint_names must be a list of names, got 'abc'"),
        ({"q_max": [1e308, 1, 1], "dq_max": [1, 1, 1], "ddq_max": [5, 5, 5]}, ValueError, "a bound this large is no bound"),
        ({"q_max": [float("nan"), 1, 1], "dq_max": [1, 1, 1], "ddq_max": [5, 5, 5]}, ValueError, "bound q_max of joint"),
    ],
)
def test_bounds_documents_are_checked_value_by_value(document, error, message):
    with pytest.raises(error, match=message):
        JointBounds.from_dict(document)


def test_ddq_max_with_a_bounds_file_is_refused_not_ignored(tmp_path, capsys):
    path = tmp_path / "bounds.json"
    path.write_text(json.dumps({"q_max": [1, 1, 1], "dq_max": [1, 1, 1], "ddq_max": [5, 5, 5]}))
    code = main(["design", "--joints", "3", "--bounds", str(path), "--ddq-max", "1", "--out", str(tmp_path / "x.json")])
    assert code == 2 and "with --bounds give ddq_max in the file" in capsys.readouterr().err


@pytest.mark.parametrize(
    "change,message",
    [
        (dict(frequency_hz=True), "frequency_hz must be a number"),
        (dict(joint_names="abc"), "joint_names must be a list of names"),
        (dict(harmonics=5.7), "harmonics must be an integer"),
        (dict(a=[[True] * 5] * 3), "coefficients a must be numbers"),
    ],
)
def test_hand_edited_trajectory_documents_are_checked_key_by_key(change, message):
    from oed.fourier import FourierTrajectory

    document = FourierTrajectory(0.2, np.zeros(3), np.full((3, 5), 0.1), np.zeros((3, 5))).to_dict()
    document.update(change)
    with pytest.raises(ValueError, match=message):
        FourierTrajectory.from_dict(document)


def test_sampling_and_settings_that_would_mislead_are_refused():
    from oed.fourier import FourierTrajectory

    trajectory = FourierTrajectory(0.2, np.zeros(1), np.full((1, 5), 0.1), np.zeros((1, 5)))
    with pytest.raises(ValueError, match="whole number of periods"):
        trajectory.sample(1000.0, periods=1.5)
    with pytest.raises(ValueError, match="rate_hz must be a positive finite number"):
        trajectory.sample(float("nan"))
    with pytest.raises(ValueError, match="111.111 samples at 1000 Hz: it must be a whole number"):
        DesignSettings(frequency_hz=9.0, harmonics=5)  # the 1 kHz check of one period would not hold on the next
    with pytest.raises(ValueError, match="constraint_points = 3 cannot bound 5 harmonics"):
        DesignSettings(constraint_points=3)
    with pytest.raises(ValueError, match="unknown key.s. q_mn"):
        JointBounds.from_dict({"q_mn": [0, 0, 0], "q_max": [1, 1, 1], "dq_max": [1, 1, 1], "ddq_max": [5, 5, 5]})
    robot = load_robot("puma560", joints=3)
    with pytest.raises(TypeError, match="seed must be a non-negative integer"):
        design_excitation(robot, starts=1, seed=np.random.default_rng(3))
    with pytest.raises(ValueError, match="starts must be an integer from 1"):
        design_excitation(robot, starts=True)


def test_design_out_named_like_another_format_is_refused(tmp_path, capsys):
    assert main(["design", "--joints", "3", "--out", str(tmp_path / "t.csv")]) == 2
    assert "this writes JSON" in capsys.readouterr().err
