"""`oed export` (dynamics.urdf_export, estimation.identification.export): a consistent identification as a URDF
and friction.json that Pinocchio's RNEA turns back into the model's prediction."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pinocchio as pin
import pytest

from dynamics.models import build_model
from dynamics.pinocchio_bridge import to_pinocchio
from dynamics.robots import load_robot
from dynamics.urdf_export import robot_urdf, urdf_with_inertials
from estimation.identification.plausibility import link_findings
from oed.cli import main
from dynamics.simulation.synthetic import simulate, true_parameters
from oed.fourier import random_fourier

NOISE = {"tau1": 0.2, "tau2": 0.2, "tau3": 0.1}


def _rnea(model, q, dq, ddq, gravity=(0.0, 0.0, -9.81)):
    model.gravity = pin.Motion(np.asarray(gravity, dtype=float), np.zeros(3))
    data = model.createData()
    return np.array([pin.rnea(model, data, a, b, c).copy() for a, b, c in zip(q, dq, ddq)])


@pytest.mark.parametrize("joints", [3, 6])
def test_a_robot_written_as_urdf_has_the_dynamics_of_its_description(joints):
    robot = load_robot("puma560", joints=joints)
    theta = robot.standard_parameters * np.random.default_rng(0).uniform(0.8, 1.2, 10 * joints)
    states = np.random.default_rng(1).normal(size=(3, 5, joints))
    written = _rnea(pin.buildModelFromXML(robot_urdf(robot, theta.reshape(-1, 10))), *states)
    assert np.allclose(written, _rnea(to_pinocchio(robot, theta=theta), *states), rtol=1e-12, atol=1e-10)


def test_a_urdf_keeps_its_names_and_gets_the_new_inertials(prismatic_urdf):
    robot = load_robot(urdf=prismatic_urdf)
    theta = robot.standard_parameters * np.random.default_rng(2).uniform(0.8, 1.2, 10 * robot.n_joints)
    text = urdf_with_inertials(prismatic_urdf.read_text(), robot, theta.reshape(-1, 10))
    written = pin.buildModelFromXML(text)
    assert list(written.names)[1:] == robot.joint_names
    states = np.random.default_rng(3).normal(size=(3, 5, robot.n_joints))
    assert np.allclose(_rnea(written, *states), _rnea(to_pinocchio(robot, theta=theta), *states), rtol=1e-12, atol=1e-10)


@pytest.fixture(scope="module")
def consistent_result(tmp_path_factory):
    """A 3-joint PUMA identified with --consistent (viscous, Coulomb, offset, armature)."""
    folder = tmp_path_factory.mktemp("export")
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", "viscous,coulomb,offset")
    theta = true_parameters(model, seed=1, coulomb=[3.0, 2.0, 1.0], offset=[0.5, -0.3, 0.2])
    paths = []
    for seed in (5, 6):
        data = simulate(model, theta, random_fourier(robot, seed=seed), rate_hz=100.0, periods=1, noise=NOISE, seed=seed)
        paths.append(folder / f"record{seed}.csv")
        data.write(paths[-1])
    result = folder / "result.json"
    assert main(["identify", "--joints", "3", "--data", str(paths[0]), "--validate", str(paths[1]), "--friction",
                 "viscous,coulomb,offset,armature", "--consistent", "--out", str(result)]) == 0
    return folder, result, paths[1]


def test_the_exported_urdf_and_friction_reproduce_oed_predict_through_pinocchio(consistent_result):
    folder, result, validate = consistent_result
    urdf, friction_path, predictions, metrics = (folder / name for name in ("out.urdf", "friction.json", "p.csv", "m.json"))
    assert main(["export", "--model", str(result), "--urdf", str(urdf), "--friction", str(friction_path)]) == 0
    assert main(["predict", "--consistent", "--model", str(result), "--data", str(validate), "--out", str(predictions),
                 "--metrics", str(metrics)]) == 0
    document = json.loads(result.read_text())
    reported = document["consistent"]["validation"]["mse"]
    measured = json.loads(metrics.read_text())["mse"]
    assert max(abs(measured[c] / reported[c] - 1) for c in reported) < 1e-6
    friction = json.loads(friction_path.read_text())
    record = pd.read_csv(validate)
    q, dq, ddq = (record[[f"{prefix}{j}" for j in (1, 2, 3)]].to_numpy() for prefix in ("q", "dq", "ddq"))
    exported = pin.buildModelFromUrdf(str(urdf))
    assert list(exported.names)[1:] == ["joint1", "joint2", "joint3"]
    tau = _rnea(exported, q, dq, ddq, friction["gravity"])
    for j, name in enumerate(["joint1", "joint2", "joint3"]):
        terms = friction["joints"][name]
        assert set(terms) == {"viscous", "coulomb", "offset", "armature"}
        tau[:, j] += (terms["viscous"] * dq[:, j] + terms["coulomb"] * np.sign(dq[:, j]) + terms["offset"]
                      + terms["armature"] * ddq[:, j])
    predicted = pd.read_csv(predictions)[["tau1", "tau2", "tau3"]].to_numpy()
    assert np.max(np.abs(tau - predicted)) / np.max(np.abs(predicted)) < 1e-6


def test_an_unconstrained_fit_is_not_exported(consistent_result, tmp_path, capsys):
    _, _, validate = consistent_result
    result = tmp_path / "plain.json"
    assert main(["identify", "--joints", "3", "--data", str(validate), "--friction", "viscous", "--method", "wls",
                 "--out", str(result)]) == 0  # an explicit method: no consistent candidate
    urdf = tmp_path / "out.urdf"
    assert main(["export", "--model", str(result), "--urdf", str(urdf)]) == 2
    error = capsys.readouterr().err
    assert "base parameters only" in error and "--consistent" in error and not urdf.exists()


def test_prior_weight_auto_takes_the_largest_weight_the_held_out_record_allows(consistent_result, tmp_path, capsys):
    folder, _, validate = consistent_result
    train = folder / "record5.csv"
    base = ["identify", "--joints", "3", "--data", str(train), "--friction", "viscous,coulomb,offset", "--consistent",
            "--prior-weight", "auto"]
    out = tmp_path / "auto.json"
    assert main([*base, "--validate", str(validate), "--out", str(out)]) == 0
    consistent = json.loads(out.read_text())["consistent"]
    search = consistent["prior_weight_search"]
    errors = {entry["prior_weight"]: entry["weighted_validation_error"] for entry in search}
    assert consistent["prior_weight"] in errors and len(errors) == 5
    best = min(errors.values())
    assert errors[consistent["prior_weight"]] <= 1.01 * best
    assert all(error > 1.01 * best for weight, error in errors.items() if weight > consistent["prior_weight"])
    assert main([*base, "--out", str(tmp_path / "none.json")]) == 2
    assert "--prior-weight auto chooses the weight by the validation error: give --validate" in capsys.readouterr().err


def test_a_consistent_body_far_from_the_description_is_named():
    robot = load_robot("puma560", joints=3)
    links = robot.standard_parameters.reshape(-1, 10).copy()
    links[1] *= 50.0  # link 2: fifty times the description's mass (and inertia): a rigid body still
    links[2] = 0.0  # link 3: nothing at all, a degenerate body
    messages = {message.split(":")[0]: message for message in link_findings(robot, links)}
    assert "against" in messages["link of joint2"] and "degenerate" in messages["link of joint3"]
    # link 2 as the description has it is named for nothing
    assert "link of joint2" not in {m.split(":")[0] for m in link_findings(robot, robot.standard_parameters)}


@pytest.mark.parametrize("change", ["heavy", "far"])
def test_an_implausible_body_is_refused_unless_allowed(consistent_result, tmp_path, capsys, change):
    _, result, _ = consistent_result
    document = json.loads(result.read_text())
    links = np.asarray(document["model_file"]["consistent"]["links"])
    if change == "heavy":  # link 2 fifty times heavier (inertias alike): a rigid body still
        links[1] *= 50.0
    else:  # link 3's centre of mass 3 m out on a 0.4 m link (the first moments moved, the mass kept)
        links[2, 1:4] = links[2, 0] * np.array([3.0, 0.0, 0.0])
        links[2, 4:] = 0.0
        links[2, [4, 6, 9]] = 0.1 + links[2, 0] * np.array([0.0, 9.0, 9.0])  # about the origin (parallel axes): real
    document["model_file"]["consistent"]["links"] = links.tolist()
    changed = tmp_path / "changed.json"
    changed.write_text(json.dumps(document))
    urdf = tmp_path / "out.urdf"
    assert main(["export", "--model", str(changed), "--urdf", str(urdf)]) == 2
    error = capsys.readouterr().err
    expected = "against" if change == "heavy" else "centre of mass"
    assert "not plausible" in error and expected in error and "--allow-implausible" in error and not urdf.exists()
    assert main(["export", "--model", str(changed), "--urdf", str(urdf), "--allow-implausible"]) == 0
    assert urdf.exists() and "exported as asked (--allow-implausible)" in capsys.readouterr().err


def test_a_centre_of_mass_beyond_the_link_is_named():
    robot = load_robot("puma560", joints=6)
    links = robot.standard_parameters.reshape(-1, 10).copy()
    mass, com = links[5, 0], np.array([0.0, 0.0, 3.6])  # the wrist link's centre of mass 3.6 m out, a real body
    about_origin = 0.01 * np.eye(3) + mass * (com @ com * np.eye(3) - np.outer(com, com))
    links[5, 1:4] = mass * com
    links[5, 4:] = about_origin[[0, 0, 1, 0, 1, 2], [0, 1, 1, 2, 2, 2]]
    messages = [message for message in link_findings(robot, links) if "centre of mass" in message]
    assert len(messages) == 1 and messages[0].startswith("link of joint6")


def test_exported_urdf_and_friction_json_simulate_again(consistent_result, tmp_path, capsys):
    """The round trip: `oed export` then `oed simulate --urdf out.urdf --effect-values friction.json`, the exported
    friction simulated with the values exported."""
    from oed.fourier import FourierTrajectory

    _, result, _ = consistent_result
    urdf, friction_path = tmp_path / "out.urdf", tmp_path / "friction.json"
    assert main(["export", "--model", str(result), "--urdf", str(urdf), "--friction", str(friction_path)]) == 0
    trajectory = tmp_path / "trajectory.json"
    generator = np.random.default_rng(4)
    FourierTrajectory(0.5, np.zeros(3), generator.uniform(-0.1, 0.1, (3, 3)),
                      generator.uniform(-0.1, 0.1, (3, 3))).save(trajectory)
    data, truth = tmp_path / "again.csv", tmp_path / "truth.json"
    capsys.readouterr()
    assert main(["simulate", "--urdf", str(urdf), "--effect-values", str(friction_path), "--trajectory",
                 str(trajectory), "--rate", "200", "--out", str(data), "--truth", str(truth)]) == 0
    captured = capsys.readouterr()
    assert "a sign law, simulated as fc · tanh(dq / 0.05)" in captured.err  # said, not silent
    friction = json.loads(friction_path.read_text())
    simulated = json.loads(truth.read_text())
    parameters = {name: value for effect in simulated["effects"] for name, value in effect["parameters"].items()}
    for j, name in enumerate(["joint1", "joint2", "joint3"], start=1):
        terms = friction["joints"][name]
        assert parameters[f"fv{j}"] == terms["viscous"] and parameters[f"fc{j}"] == terms["coulomb"]
        assert parameters[f"off{j}"] == terms["offset"] and parameters[f"Ia{j}"] == terms["armature"]
    assert len(pd.read_csv(data)) == 400


def test_the_exported_mjcf_reproduces_oed_predict_through_mujoco_inverse_dynamics(consistent_result, tmp_path,
                                                                                   capsys):
    """MuJoCo loads the MJCF; with friction loss (and limits) disabled, mj_inverse on the validation record is
    `oed predict --consistent` less its Coulomb term and its offset (which MuJoCo cannot express, and which the
    file and the verb's output list); frictionloss, damping and armature are the exported coefficients."""
    mujoco = pytest.importorskip("mujoco", reason="the mujoco extra is not installed: pip install 'robot-oed[mujoco]'")
    folder, result, validate = consistent_result
    mjcf, friction_path, predictions = tmp_path / "robot.xml", tmp_path / "friction.json", tmp_path / "p.csv"
    capsys.readouterr()
    assert main(["export", "--model", str(result), "--mjcf", str(mjcf), "--friction", str(friction_path)]) == 0
    output = capsys.readouterr().out
    text = mjcf.read_text()
    for name in ("joint1", "joint2", "joint3"):
        assert f"joint {name}: offset" in output and f"joint {name}: offset" in text  # listed, not dropped
    assert main(["predict", "--consistent", "--model", str(result), "--data", str(validate), "--out",
                 str(predictions)]) == 0
    friction = json.loads(friction_path.read_text())
    terms = [friction["joints"][name] for name in ("joint1", "joint2", "joint3")]
    model = mujoco.MjModel.from_xml_path(str(mjcf))
    np.testing.assert_array_equal(model.dof_frictionloss, [entry["coulomb"] for entry in terms])
    np.testing.assert_array_equal(model.dof_damping, [entry["viscous"] for entry in terms])
    np.testing.assert_array_equal(model.dof_armature, [entry["armature"] for entry in terms])
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS | mujoco.mjtDisableBit.mjDSBL_LIMIT
    data = mujoco.MjData(model)
    record = pd.read_csv(validate)
    q, dq, ddq = (record[[f"{prefix}{j}" for j in (1, 2, 3)]].to_numpy() for prefix in ("q", "dq", "ddq"))
    inverse = []
    for qi, dqi, ddqi in zip(q, dq, ddq):
        data.qpos[:], data.qvel[:], data.qacc[:] = qi, dqi, ddqi
        mujoco.mj_inverse(model, data)
        inverse.append(data.qfrc_inverse.copy())
    predicted = pd.read_csv(predictions)[["tau1", "tau2", "tau3"]].to_numpy()
    expected = predicted - np.array([entry["coulomb"] for entry in terms]) * np.sign(dq) \
        - np.array([entry["offset"] for entry in terms])
    np.testing.assert_allclose(np.array(inverse), expected, rtol=0, atol=1e-6 * np.abs(expected).max())
    # numbers at full precision: the file reads back the doubles exported
    assert repr(terms[0]["coulomb"]) in text


@pytest.mark.parametrize(("outputs", "named"), [
    ({"urdf": "model.txt"}, "--urdf model.txt: this writes a URDF; give a .urdf file name"),
    ({"urdf": "m.urdf", "mjcf": "j.urdf"}, "--mjcf j.urdf: this writes MuJoCo's MJCF; give an .xml file name"),
    ({"urdf": "m.urdf", "friction": "f.csv"}, "--friction f.csv: this writes JSON; give a .json file name")])
def test_a_wrong_suffix_is_refused_by_the_library_as_by_the_command_line(consistent_result, tmp_path, capsys,
                                                                          outputs, named):
    """``oed.export(...).write("x.txt")`` refuses as ``oed export --urdf x.txt`` does: a typed error naming the
    option and the suffix wanted, and nothing written."""
    import oed
    from oed.workflows.options import OutputPathError

    _, result, _ = consistent_result
    run = oed.export(model=result, mjcf=True)
    paths = {key: tmp_path / name for key, name in outputs.items()}
    option, name = named.split(" ", 1)[0], named.split(" ", 1)[1]
    with pytest.raises(OutputPathError) as refused:
        run.write(paths.pop("urdf"), **paths)
    assert str(refused.value).startswith(f"{option} {tmp_path}/") and str(refused.value).endswith(name)
    assert isinstance(refused.value, ValueError)
    assert list(tmp_path.iterdir()) == []
    options = [item for key, name in outputs.items() for item in (f"--{key}", str(tmp_path / name))]
    assert main(["export", "--model", str(result), *options]) == 2
    assert named.split(": ", 1)[1] in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
