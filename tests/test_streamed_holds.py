"""The streamed path cuts a training record's holds out of the fit as in memory (issue 34, "one answer per result";
h-unseen6: :func:`estimation.identification.prepared.training_without_holds`).

At 7f2677d the streamed path only zeroed a hold's derivatives: on the PUMA 3 halted for half its 8 s training record
(``--chunk-size 300``, the hold of 1000 rows spanning four chunk edges) ``oed identify`` validated at
0.524 / 1.207 / 6.119 N²m² where in memory (the hold cut) it validates at 0.593 / 1.486 / 5.213."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from dynamics.measurements import Measurements
from dynamics.models import build_model
from dynamics.robots import load_robot


def test_a_training_file_is_cut_at_its_holds_in_parts_as_in_memory(tmp_path):
    """One pass over the file in blocks of 64 rows finds the holds the in-memory cut finds (one across block edges,
    one after a hole), and its parts are the in-memory parts, row for row; a file without a hold is left whole."""
    from estimation.data import HoldWarning
    from estimation.data.rest import without_holds
    from estimation.streaming.chunks import read_chunks, segment_sources

    model = build_model(load_robot("puma560", joints=2), "internal", "viscous,coulomb,offset")
    t = np.r_[np.arange(0.0, 2.0, 0.004), np.arange(2.5, 3.5, 0.004)]  # a hole of 0.5 s at row 500
    q = np.column_stack([np.sin(3 * t), np.cos(2 * t)])
    q[100:230] = q[100]  # 0.516 s held, across the blocks' edges at 128 and 192
    q[560:600] = q[560]  # after the hole: 0.156 s held
    q[300:310] = q[300]  # 36 ms: not a hold
    frame = pd.DataFrame({"t": t, "q1": q[:, 0], "q2": q[:, 1], "tau1": np.sin(t), "tau2": np.cos(t)})
    frame.to_csv(tmp_path / "train.csv", index=False)
    memory, dropped = [], 0
    for rows in (slice(0, 500), slice(500, None)):
        segment = Measurements(t[rows], q[rows], None, None, frame[["tau1", "tau2"]].to_numpy()[rows], None, {})
        parts, left = without_holds(segment, 0.05)
        memory, dropped = [*memory, *parts], dropped + left
    assert dropped == 130 + 40
    with pytest.warns(HoldWarning, match=r"held still .* on 170 of 750 rows"):
        sources = segment_sources([tmp_path / "train.csv"], model, chunk_size=64, holds_cut=True)
    assert [str(source) for source in sources] == [f"{tmp_path / 'train.csv'} (part {index})" for index in (1, 2, 3, 4)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for source, part in zip(sources, memory, strict=True):
            chunks = list(read_chunks(source, model, chunk_size=64))
            assert np.array_equal(np.concatenate([chunk.t for chunk in chunks]), part.t)
            assert np.array_equal(np.concatenate([chunk.q for chunk in chunks]), part.q)
        assert segment_sources([tmp_path / "train.csv"], model, chunk_size=64) == [
            tmp_path / f"train.csv (segment {index})" for index in (1, 2)]  # validation and test: as recorded
        frame.assign(q1=np.sin(3 * t), q2=np.cos(2 * t)).to_csv(tmp_path / "moving.csv", index=False)
        moving = segment_sources([tmp_path / "moving.csv"], model, chunk_size=64, holds_cut=True)
    assert moving == [tmp_path / f"moving.csv (segment {index})" for index in (1, 2)]


def halted_records(folder):
    from tests.test_unseen_robot_labs import Lab, Log, puma, write_records

    case = Lab("halted", puma(3), *(Log(seconds, 250.0, velocity=False) for seconds in (8.0, 3.0, 3.0)), halted=0.5)
    _, _, files, _ = write_records(case, folder)
    return files


@pytest.mark.slow
@pytest.mark.parametrize("verb", ["identify", "diagnose"])
def test_the_streamed_verbs_cut_a_hold_across_chunk_edges_as_in_memory(tmp_path, verb):
    """The PUMA 3 halted for half its training record: streamed (``--chunk-size 300``, the hold's 1000 rows across
    four chunk edges) and in memory give the same warning and validation errors (relative 1e-9)."""
    import oed

    files = halted_records(tmp_path)
    errors = {}
    for label, chunk in (("memory", {}), ("streamed", {"chunk_size": 300})):
        run = getattr(oed, verb)(urdf=tmp_path / "robot.urdf", data=files["train"], validate=files["validate"],
                                 **chunk)
        held = [text for text in run.warnings if "held still" in text]
        assert len(held) == 1 and "on 1000 of 2000 rows" in held[0], (label, run.warnings)
        document = run.to_dict()
        assert (document["streaming"] is not None) == (label == "streamed")
        validation = document["validation"]
        errors[label] = validation["mse"] if verb == "identify" else validation["after"]["mse"]
    for channel, error in errors["memory"].items():
        assert errors["streamed"][channel] == pytest.approx(error, rel=1e-9), channel
