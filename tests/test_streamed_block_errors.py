"""The validation record's blocks summed on the streamed path (:mod:`estimation.streaming.block_errors`): the blocks
memory cuts its samples into (:func:`numpy.array_split`), their squared errors summed as the rows pass or from each
block's normal equations, and the paired difference of two candidates from them equal to memory's
(:func:`estimation.consistent.model_selection.paired_difference`). The verbs' parity, in memory against streamed:
``tests/test_memory_path.py::test_identify_chooses_the_same_model_in_memory_and_streamed``."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from dynamics.measurements import Measurements
from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.consistent.model_selection import Candidate, paired_difference
from estimation.identification.preprocessing_on_validation import BLOCKS, block_mse
from estimation.identification.validation import ChannelErrors, Comparison
from estimation.streaming.block_errors import (
    BlockSquares,
    block_channel_mse,
    block_normal_equations,
    block_sizes,
)

CHANNELS = ("tau1", "tau2")


@pytest.mark.parametrize("n_samples", [5, 6, 9, 10, 11, 1003, 2000])
def test_the_blocks_are_those_numpy_array_split_cuts(n_samples):
    expected = [part.shape[0] for part in np.array_split(np.empty(n_samples), BLOCKS)]
    assert block_sizes(n_samples).tolist() == expected


def _comparison(seed, samples):
    generator = np.random.default_rng(seed)
    t = np.arange(samples) / 500.0
    measured = np.column_stack([np.sin(2 * np.pi * 0.5 * t), 0.1 * np.cos(2 * np.pi * 0.7 * t)])
    predicted = measured + generator.normal(0, [0.05, 0.005], measured.shape) + 0.02 * np.sin(3 * t)[:, None]
    return Comparison(t, measured, predicted, CHANNELS)


@pytest.mark.parametrize("samples", [1003, 1500])
def test_squares_summed_as_the_rows_pass_give_memorys_block_errors(samples):
    comparison = _comparison(1, samples)
    squares = BlockSquares(samples, len(CHANNELS))
    generator = np.random.default_rng(2)
    start = 0
    while start < samples:  # chunks of any size, across the blocks' bounds
        stop = min(samples, start + int(generator.integers(1, 400)))
        squares.add(comparison.residuals[start:stop] ** 2)
        start = stop
    expected = block_mse(comparison)
    summed = squares.block_mse(CHANNELS)
    assert summed.keys() == expected.keys()
    for channel in CHANNELS:
        np.testing.assert_allclose(summed[channel], expected[channel], rtol=1e-12)
    short = BlockSquares(samples + 1, len(CHANNELS))  # a pass that gave other rows than announced: no blocks
    short.add(comparison.residuals ** 2)
    assert short.block_mse(CHANNELS) is None
    assert BlockSquares(3, len(CHANNELS)).block_mse(CHANNELS) is None  # fewer rows than blocks
    spoiled = BlockSquares(samples, len(CHANNELS))  # rows out of their order (stamps before a grid's start)
    spoiled.add(comparison.residuals ** 2)
    spoiled.spoil()
    assert spoiled.block_mse(CHANNELS) is None


def test_the_blocks_normal_equations_give_each_blocks_error_of_any_parameters():
    model = build_model(load_robot("puma560", joints=3), "internal", "viscous")
    generator = np.random.default_rng(3)
    samples = 1203
    t = np.arange(samples) / 200.0
    q = np.column_stack([np.sin(0.7 * t + phase) for phase in (0.0, 1.0, 2.0)])
    dq = np.column_stack([0.7 * np.cos(0.7 * t + phase) for phase in (0.0, 1.0, 2.0)])
    ddq = -0.49 * q
    tau = generator.normal(0, 1.0, (samples, 3))
    record = Measurements(t, q, dq=dq, ddq=ddq, tau=tau)
    chunks = [record.select(slice(start, start + 250)) for start in range(0, samples, 250)]
    sums = block_normal_equations(model, chunks, samples)
    assert sums is not None and [part.n_samples for part in sums] == block_sizes(samples).tolist()
    assert block_normal_equations(model, chunks, samples - 1) is None
    Y = model.evaluate_base(q, dq, ddq)
    for theta in (np.zeros(model.n_base), generator.normal(0, 1.0, model.n_base)):
        predicted = np.einsum("nck,k->nc", Y, theta)
        expected = block_mse(Comparison(t, tau, predicted, model.channels))
        got = block_channel_mse(sums, theta)
        for channel in model.channels:
            np.testing.assert_allclose(got[channel], expected[channel], rtol=1e-9)


def _summed(name, comparison, blocks=True):
    errors = ChannelErrors(dict(comparison.mse), comparison.n_samples,
                           block_mse=block_mse(comparison) if blocks else None)
    return Candidate(name, SimpleNamespace(validation=errors, train=None))


def test_the_paired_difference_from_block_sums_is_memorys():
    first, second = _comparison(4, 1503), _comparison(5, 1503)  # blocks of 301 and 300 samples
    held = [Candidate(name, SimpleNamespace(validation=item, train=None))
            for name, item in (("wls", first), ("consistent", second))]
    memory = paired_difference(held, "wls")
    streamed = paired_difference([_summed("wls", first), _summed("consistent", second)], "wls")
    assert memory is not None and streamed is not None
    assert streamed.difference == pytest.approx(memory.difference, rel=1e-12)
    assert streamed.standard_error == pytest.approx(memory.standard_error, rel=1e-12)
    # the blocks of a resampled file's recorded samples, whose sums count the grid's: cut from the recorded count
    gridded = [Candidate(name, SimpleNamespace(validation=ChannelErrors(
        dict(item.mse), 2 * item.n_samples, block_mse=block_mse(item), block_samples=item.n_samples), train=None))
        for name, item in (("wls", first), ("consistent", second))]
    assert paired_difference(gridded, "wls").standard_error == pytest.approx(memory.standard_error, rel=1e-12)
    # no blocks summed, other samples, or one held and one summed: nothing compared
    assert paired_difference([_summed("wls", first, blocks=False), _summed("consistent", second)], "wls") is None
    assert paired_difference([_summed("wls", first), _summed("consistent", _comparison(5, 1502))], "wls") is None
    assert paired_difference([held[0], _summed("consistent", second)], "wls") is None


def _jittered_records(folder) -> list:
    """Training and validation logs of a 3-joint PUMA (3 periods at 200 Hz each, another motion each; Coulomb
    friction on joint 2 and an offset on joint 1 beside viscous friction) whose stamps jitter by 20 % of a step."""
    from dynamics.effects.linear import CoulombFriction, JointOffset
    from dynamics.simulation.synthetic import simulate, true_parameters
    from oed.fourier import random_fourier

    model = build_model(load_robot("puma560", joints=3), "internal", "viscous")
    truth = build_model(model.robot, "internal", ("viscous", CoulombFriction(joints=(1,)), JointOffset(joints=(0,))))
    theta = true_parameters(truth, seed=0, coulomb=[8.0], offset=[3.0])
    generator = np.random.default_rng(5)
    paths = []
    for seed, trajectory in ((1, 3), (2, 4)):
        data = simulate(truth, theta, random_fourier(model.robot, seed=trajectory),
                        noise={c: 0.2 for c in truth.channels}, seed=seed, rate_hz=200.0, periods=3)
        t = data.t + generator.uniform(-0.2, 0.2, data.t.shape) / 200.0
        Measurements(t, data.q + 1e-4 * generator.standard_normal(data.q.shape), tau=data.tau).write(
            folder / f"jittered{seed}.csv")
        paths.append(folder / f"jittered{seed}.csv")
    return paths


@pytest.mark.slow
def test_a_jittered_validation_record_gives_memorys_paired_difference_streamed(tmp_path):
    """A log whose stamps jitter by 20 % of a step (the streamed reader resamples it onto a grid and scores the
    candidates at the recorded stamps): the streamed ``oed identify`` learns the recorded samples' count on its first
    pass and sums the blocks on one more, and reports memory's paired difference (measured 3e-12 apart; ``null``
    before, h-shortval)."""
    import json

    from oed.cli import main

    paths = _jittered_records(tmp_path)
    documents = {}
    for name, options in (("memory", ()), ("streamed", ("--chunk-size", "250"))):
        out = tmp_path / f"{name}.json"
        assert main(["identify", "--joints", "3", "--model", "internal", "--friction", "viscous,coulomb,offset",
                     "--data", str(paths[0]), "--validate", str(paths[1]), "--out", str(out), "--cutoff", "6",
                     "--quiet", *options]) == 0
        documents[name] = json.loads(out.read_text())
    memory, streamed = documents["memory"], documents["streamed"]
    assert streamed["streaming"]["validation_files"][0]["resampled_from"] is not None  # scored at the stamps
    assert streamed["chosen"] == memory["chosen"] != "consistent"
    paired = {name: document["model_selection"]["paired_difference"] for name, document in documents.items()}
    assert paired["memory"] is not None and paired["streamed"] is not None
    assert paired["streamed"]["best"] == paired["memory"]["best"]
    for key in ("difference", "standard_error"):
        assert paired["streamed"][key] == pytest.approx(paired["memory"][key], rel=1e-8), key
    weighting = {name: document["model_selection"]["weighting_difference"] for name, document in documents.items()}
    assert (weighting["memory"] is None) == (weighting["streamed"] is None)  # wls scoring lower in both or neither
    for key in ("difference", "standard_error") if weighting["memory"] is not None else ():
        assert weighting["streamed"][key] == pytest.approx(weighting["memory"][key], rel=1e-8), key


@pytest.mark.slow
def test_the_streamed_diagnosis_reports_the_paired_difference_predict_measures_at_the_stamps(tmp_path):
    """The streamed ``oed diagnose`` on a validation log whose stamps jitter (resampled onto a grid by the streamed
    reader; its candidates scored at the recorded stamps, as ``oed predict`` measures them) reports the paired
    difference of its answer and the consistent refit (``null`` before, h-streamdiag), equal to the one recomputed
    from ``oed predict``'s residuals of each model at those stamps, cut into memory's blocks (measured: 1e-9 apart)."""
    import json

    import pandas as pd

    from estimation.identification.preprocessing_on_validation import paired_difference as blocks_difference
    from oed.cli import main

    model = build_model(load_robot("puma560", joints=3), "internal", "viscous")
    paths = _jittered_records(tmp_path)
    out = tmp_path / "streamed.json"
    assert main(["diagnose", "--joints", "3", "--model", "internal", "--friction", "viscous", "--data", str(paths[0]),
                 "--validate", str(paths[1]), "--out", str(out), "--cutoff", "6", "--quiet", "--chunk-size",
                 "250"]) == 0
    document = json.loads(out.read_text())
    assert document["streaming"]["validation_files"][0]["resampled_from"] is not None  # scored at the stamps
    selection = document["model_selection"]
    paired = selection["paired_difference"]
    assert paired is not None and paired["regularised"] == "consistent" and paired["best"] == selection["chosen"]
    residuals = {}
    for name in (paired["best"], "consistent"):
        predictions = tmp_path / f"{name}.csv"
        assert main(["predict", "--model", str(out), "--data", str(paths[1]), "--alternative", name, "--out",
                     str(predictions)]) == 0
        table = pd.read_csv(predictions)
        residuals[name] = table[[f"{channel}_residual" for channel in model.channels]].to_numpy()
    validation = {candidate["name"]: candidate["validation_mse"] for candidate in selection["candidates"]}
    for name, residual in residuals.items():  # each candidate's score is predict's error at the stamps
        np.testing.assert_allclose(np.mean(residual ** 2, axis=0), [validation[name][c] for c in model.channels],
                                   rtol=1e-8)
    floors = np.min([[mse[c] for c in model.channels] for mse in validation.values()], axis=0)
    blocks = {name: {c: tuple(float(part[:, j].mean()) for part in np.array_split(residual ** 2, BLOCKS))
                     for j, c in enumerate(model.channels)} for name, residual in residuals.items()}
    sizes = np.array([part.shape[0] for part in np.array_split(residuals["consistent"], BLOCKS)], dtype=float)
    difference, error = blocks_difference(blocks["consistent"], blocks[paired["best"]], floors, model.channels, sizes)
    assert paired["difference"] == pytest.approx(difference, rel=1e-6)
    assert paired["standard_error"] == pytest.approx(error, rel=1e-6)


@pytest.mark.slow  # two diagnoses: about 20 s
def test_the_streamed_search_on_a_jittered_log_confirms_its_candidates_at_the_stamps_as_memory(tmp_path):
    """The streamed search confirms its candidates on the validation record as logged (the torques at their stamps,
    the motion interpolated there) as memory does; the check that the resampled grid spans every stamp missed the
    last one by a rounding of the grid (14.995752719999999 against 14.99575272 s), so the search validated on the
    grid's interpolated torques and named a sigmoid on tau2 where memory names Coulomb friction (validation MSE tau2
    0.1035 against 0.0594 N²m²). Now: memory's effects, parameters, validation errors and paired difference
    (1e-6; measured 1e-10)."""
    import json

    from oed.cli import main

    paths = _jittered_records(tmp_path)
    documents = {}
    for name, options in (("memory", ()), ("streamed", ("--chunk-size", "250"))):
        out = tmp_path / f"{name}.json"
        assert main(["diagnose", "--joints", "3", "--model", "internal", "--friction", "viscous", "--data",
                     str(paths[0]), "--validate", str(paths[1]), "--out", str(out), "--cutoff", "6", "--quiet",
                     *options]) == 0
        documents[name] = json.loads(out.read_text())
    memory, streamed = documents["memory"], documents["streamed"]
    assert streamed["diagnosis_path"] == "streamed"
    found = [(effect["spec"], effect["channels"]) for effect in streamed["effects"]]
    assert found == [(effect["spec"], effect["channels"]) for effect in memory["effects"]]
    assert ("coulomb", ["tau2"]) in found
    assert streamed["model_selection"]["chosen"] == memory["model_selection"]["chosen"]
    np.testing.assert_allclose(streamed["model_file"]["theta"], memory["model_file"]["theta"], rtol=1e-6, atol=1e-9)
    for which in ("after", "chosen"):
        assert streamed["validation"][which]["mse"] == pytest.approx(memory["validation"][which]["mse"], rel=1e-6)
    paired = [document["model_selection"]["paired_difference"] for document in (memory, streamed)]
    for key in ("difference", "standard_error"):
        assert paired[1][key] == pytest.approx(paired[0][key], rel=1e-6), key
