"""Motor-side records (``--transmission``), given joint zeros (``--joint-offsets``) and the motor-side friction
candidate on the streamed path (records read in blocks: ``--chunk-size``, or past ``--memory-budget``): the same
answer as in memory.

* :func:`estimation.data.motor_side.joint_side_copies` writes, block by block, what the in-memory reader makes of a
  motor-side record with joint offsets and directions (:func:`read_record_with_transmission`), and refuses a gear of
  the wrong sign on the whole record as the in-memory reader does;
* ``oed identify`` and ``oed diagnose`` streamed with ``--transmission`` and ``--joint-offsets`` give the in-memory
  estimate, model file (the transmission and the zeros in it) and effects; what they write names the files as given;
* the streamed default ``oed identify`` tries motor-side friction on a coupled transmission as in memory
  (:func:`oed.workflows.identify.streamed_motor_friction_selection`): on a simulated PUMA with the Stäubli TX40's
  coupled wrist (slow) and on the real TX40 log (slow, skipped without ``../shared/data``), the same chosen model,
  effects, reason and errors.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

import oed
from dynamics.robots import load_robot
from dynamics.models import build_model
from dynamics.transmission import JointDirections, Transmission, TransmissionSignError
from estimation.data.motor_side import joint_side_copies, read_record_with_transmission
from estimation.data.records import read_record
from oed.cli import main
from tests.conftest import SHARED_DATA
from tests.test_joint_offsets import OFFSETS, RATIOS, joint_side, logs  # noqa: F401  (fixtures)

DIRECTIONS = JointDirections((1.0, -1.0, 1.0), (1.0, -1.0, -1.0))


def test_joint_side_copies_hold_what_the_in_memory_reader_reads(logs, tmp_path):  # noqa: F811
    """Motor side with the encoders' zeros, directions and offsets, converted in blocks of 97 rows: the segments
    read from the copy equal those the in-memory reader makes of the motor-side file."""
    robot = load_robot("puma560", joints=3)
    model = build_model(robot, "internal", "viscous")
    transmission = Transmission(np.diag(RATIOS), offsets=OFFSETS)
    offsets = np.array([0.01, -0.02, 0.03])
    source = logs / "train_motor.csv"
    (copy,) = joint_side_copies([source], tmp_path, n_joints=3, transmission=transmission, joint_offsets=offsets,
                                joint_directions=DIRECTIONS, chunk_size=97)
    assert copy != source and copy.suffix == ".parquet"
    expected = read_record_with_transmission(source, model=model, transmission=transmission, joint_offsets=offsets,
                                             joint_directions=DIRECTIONS)
    read = read_record(copy, model=model)
    assert len(read) == len(expected) == 1
    for name in ("t", "q", "dq", "ddq", "tau"):
        np.testing.assert_allclose(getattr(read[0], name), getattr(expected[0], name), rtol=1e-14, atol=1e-14,
                                   err_msg=name)
    # a joint-side file without offsets or motor columns is read as it is
    assert joint_side_copies([logs / "train.csv"], tmp_path / "none", n_joints=3, transmission=None) == \
        [logs / "train.csv"]


def test_a_gear_of_the_wrong_sign_is_refused_on_the_whole_record(tmp_path):
    """The power-sign check of the in-memory reader, on the sums of the blocks: joint-side positions (link encoders)
    beside motor torques whose ratio has the wrong sign for the data are refused, naming the joint, as in memory."""
    t = np.arange(0, 4, 0.002)
    q = np.column_stack([np.sin(t), 0.5 * np.sin(2 * t)])
    dq = np.column_stack([np.cos(t), np.cos(2 * t)])
    tau = 2.0 * dq + 0.1  # friction: dissipates
    transmission = Transmission(np.diag([10.0, -10.0]))  # joint 2's ratio of the wrong sign for the data
    taum = tau / 10.0  # link encoders (joint side), motor torques
    frame = pd.DataFrame({"t": t, "q1": q[:, 0], "q2": q[:, 1], "taum1": taum[:, 0], "taum2": taum[:, 1]})
    frame.to_csv(tmp_path / "log.csv", index=False)
    robot = load_robot("puma560", joints=2)
    with pytest.raises(TransmissionSignError, match="joint 2") as in_memory:
        read_record_with_transmission(tmp_path / "log.csv", model=build_model(robot, "internal", "viscous"),
                                      transmission=transmission)
    with pytest.raises(TransmissionSignError, match="joint 2") as streamed:
        joint_side_copies([tmp_path / "log.csv"], tmp_path / "copies", n_joints=2, transmission=transmission,
                          chunk_size=300)
    assert str(streamed.value).split("(mean power")[0] == str(in_memory.value).split("(mean power")[0]


def _json(path) -> dict:
    return json.loads(path.read_text())


@pytest.mark.parametrize("streamed", [["--chunk-size", "250"], ["--memory-budget", "1KB"]])
def test_identify_streamed_with_transmission_and_joint_offsets(joint_side, tmp_path, streamed):  # noqa: F811
    """``--transmission`` (motor-side records whose encoders read zero at ``OFFSETS``) and ``--joint-offsets``
    (joint-side records logged in those zeros), each streamed against in memory: the same estimate (1e-6), model
    file's transmission and zeros, and ``oed predict`` with the streamed file reproduces the in-memory prediction."""
    folder = joint_side
    runs = {"transmission": (["--transmission", str(folder / "with_offsets.json")], "train_motor.csv",
                             "val_motor.csv"),
            "offsets": (["--joint-offsets", str(folder / "offsets.json")], "train_zeroed.csv", "val_zeroed.csv")}
    for label, (option, train, validate) in runs.items():
        documents = {}
        for path, extra in (("memory", []), ("streamed", streamed)):
            out = tmp_path / f"{label}_{path}.json"
            assert main(["identify", "--robot", "puma560", "--joints", "3", "--data", str(folder / train),
                         "--validate", str(folder / validate), "--friction", "viscous", "--method", "ols",
                         "--cutoff", "20", "--quiet", *option, *extra, "--out", str(out)]) == 0
            documents[path] = _json(out)
            assert "oed-joint-side-" not in out.read_text()  # the files as given, never their copies
        memory, stream = documents["memory"], documents["streamed"]
        assert memory["identification_path"] == "in-memory" and stream["identification_path"] == "streamed"
        np.testing.assert_allclose(stream["model_file"]["theta"], memory["model_file"]["theta"], rtol=1e-6, atol=1e-8)
        for key in ("transmission", "joint_offsets", "joint_directions"):
            assert stream["model_file"].get(key) == memory["model_file"].get(key), key
        assert [record["path"] for record in stream["streaming"]["files"]] == [str(folder / train)]
        predicted = {}
        for path in ("memory", "streamed"):
            assert main(["predict", "--model", str(tmp_path / f"{label}_{path}.json"), "--data",
                         str(folder / validate), "--out", str(tmp_path / f"{label}_{path}.csv")]) == 0
            predicted[path] = pd.read_csv(tmp_path / f"{label}_{path}.csv")[["tau1", "tau2", "tau3"]].to_numpy()
        np.testing.assert_allclose(predicted["streamed"], predicted["memory"], rtol=1e-6, atol=1e-8)


def test_diagnose_streamed_with_transmission(joint_side, tmp_path):  # noqa: F811
    """``oed diagnose --transmission`` on motor-side records, streamed against in memory: the same effects named
    and the model file's transmission; the estimate within the streamed search's tolerance."""
    folder = joint_side
    documents = {}
    for path, extra in (("memory", []), ("streamed", ["--chunk-size", "500"])):
        out = tmp_path / f"diagnose_{path}.json"
        assert main(["diagnose", "--robot", "puma560", "--joints", "3", "--data", str(folder / "train_motor.csv"),
                     "--validate", str(folder / "val_motor.csv"), "--transmission", str(folder / "with_offsets.json"),
                     "--quiet", *extra, "--out", str(out)]) == 0
        documents[path] = _json(out)
        assert "oed-joint-side-" not in out.read_text()
    memory, stream = documents["memory"], documents["streamed"]
    assert stream["diagnosis_path"] == "streamed"
    assert [e["spec"] for e in stream["model_file"]["effect_values"]] == \
        [e["spec"] for e in memory["model_file"]["effect_values"]]
    assert stream["model_file"]["transmission"] == memory["model_file"]["transmission"]
    assert stream["transmission"]["matrix"] == memory["transmission"]["matrix"]
    np.testing.assert_allclose(stream["model_file"]["theta"], memory["model_file"]["theta"], rtol=1e-4, atol=1e-6)


def _coupled_wrist(folder, extra: str):
    from tests.test_motor_friction_candidate import reality
    from tests.test_unseen_robot_realities import write_records

    _, _, files, _, options = write_records(reality(extra), folder)
    return files, options[options.index("--transmission") + 1]


@pytest.mark.slow
@pytest.mark.parametrize("extra, taken", [("coupled motor friction", True), ("", False)])
def test_the_streamed_identify_tries_motor_friction_as_in_memory(tmp_path, extra, taken):
    """A PUMA with the TX40's coupled wrist logged on the motor side, the truth's friction at motor 6 (taken) or
    per joint (not taken): in memory, ``--chunk-size 500`` and ``--memory-budget 1KB`` choose the same model with
    the same effects and reason (the scores as printed), the chosen model's validation error and parameters to
    1e-6, and ``oed predict`` reproduces the streamed run's validation error."""
    files, transmission = _coupled_wrist(tmp_path, extra)
    from tests.test_unseen_robots import FRICTION

    documents = {}
    for label, options in (("memory", {}), ("chunk", {"chunk_size": 500}), ("budget", {"memory_budget": "1KB"})):
        run = oed.identify(urdf=tmp_path / "robot.urdf", data=(files["train"],), validate=(files["validate"],),
                           friction=FRICTION, transmission=transmission, **options)
        run.write(tmp_path / f"{label}.json")
        documents[label] = _json(tmp_path / f"{label}.json")
    memory = documents["memory"]
    assert memory["model_selection"]["reason"].endswith("taken")
    assert ("motor_viscous@6" in memory["model_file"]["effects"]) is taken
    for label in ("chunk", "budget"):
        stream = documents[label]
        assert stream["identification_path"] == "streamed" and "motor_friction" not in stream["not_computed"]
        assert stream["model_file"]["effects"] == memory["model_file"]["effects"]
        assert stream["model_selection"]["chosen"] == memory["model_selection"]["chosen"]
        assert stream["model_selection"]["reason"] == memory["model_selection"]["reason"]
        for channel, value in memory["validation"]["mse"].items():
            assert stream["validation"]["mse"][channel] == pytest.approx(value, rel=1e-6)
        np.testing.assert_allclose(stream["model_file"]["theta"], memory["model_file"]["theta"], rtol=1e-6,
                                   atol=1e-9)
    metrics = tmp_path / "metrics.json"
    assert main(["predict", "--model", str(tmp_path / "chunk.json"), "--data", str(files["validate"]), "--out",
                 str(tmp_path / "predicted.csv"), "--metrics", str(metrics)]) == 0
    for channel, value in documents["chunk"]["validation"]["mse"].items():
        assert _json(metrics)["mse"][channel] == pytest.approx(value, rel=1e-6)


@pytest.mark.slow
def test_the_real_tx40_streamed_gives_the_in_memory_answer(tmp_path):
    """The Stäubli TX40's motor-side log (``bench_real_robots.py``'s roles, ``--transmission``), forced to stream by
    ``--memory-budget 1KB``: the default ``oed identify`` takes the motor-side friction candidate as in memory, the
    same reason, and ``oed predict`` gives the same test error per joint (1e-6)."""
    if not (SHARED_DATA / "tx40").is_dir():
        pytest.skip(f"the Stäubli TX40 log is not in {SHARED_DATA} (see its README)")
    from benchmarks import bench_real_robots as bench

    case = bench.tx40(tmp_path)
    runs = {label: bench.toolkit(case, tmp_path, label, options)
            for label, options in (("memory", []), ("budget", ["--memory-budget", "1KB"]))}
    memory, budget = runs["memory"]["result"], runs["budget"]["result"]
    assert budget["identification_path"] == "streamed"
    assert "motor_viscous@6" in memory["model_file"]["effects"]
    assert budget["model_file"]["effects"] == memory["model_file"]["effects"]
    assert budget["model_selection"]["reason"] == memory["model_selection"]["reason"]
    test = case.records["test"]
    errors = {}
    for label, run in runs.items():
        index, values = bench.at_recorded(test.t, run["t"], run["predicted"])
        errors[label] = np.mean((values - test.tau[index]) ** 2, axis=0)
    np.testing.assert_allclose(errors["budget"], errors["memory"], rtol=1e-6)
