"""The streamed ``oed diagnose`` (``--chunk-size``, or a record past ``--memory-budget``) names the effects the
in-memory one names (issue 34: "the result must not depend on ... the free memory of the machine").

On the measured KUKA LWR4+ log (run 1 trained, run 2 validating) the streamed search named 20 effects against 14 in
memory: its Wald tests took the classical covariance of the summed fit, which residuals correlated in time make far
too confident, where the in-memory search takes the HAC covariance; and its final fit kept findings within their
noise (p = 0.12, 0.16) that the in-memory final refit drops. Both now as in memory
(:func:`estimation.streaming.diagnosis.robust_covariance`, the batch-means sandwich of a pass over the training files;
the final fit's weakest finding within its noise dropped and the rest refitted).
"""

from __future__ import annotations

import pandas as pd
import pytest

from estimation.datasets.kuka import load_kuka_run
from oed import diagnose
from tests.conftest import shared_data

pytestmark = [pytest.mark.realdata, pytest.mark.slow]


def _write(folder, index, path):
    run = load_kuka_run(folder / f"kuka_lwr4_HW_measurements_{index}.npz")
    frame = {"t": run.t}
    for name, values in (("q", run.q), ("dq", run.dq), ("ddq", run.ddq), ("tau", run.tau)):
        frame.update({f"{name}{j + 1}": values[:, j] for j in range(values.shape[1])})
    pd.DataFrame(frame).to_csv(path, index=False, float_format="%.17g")
    return path


def _effects(document):
    return {(entry["spec"], tuple(entry["channels"])) for entry in document["effects"]}


def test_the_streamed_diagnosis_of_the_kuka_names_the_in_memory_effects(tmp_path):
    folder = shared_data("kuka_lwr4")
    urdf = folder / "kuka_lwr4.urdf"
    train, validate = _write(folder, 1, tmp_path / "train.csv"), _write(folder, 2, tmp_path / "validate.csv")
    runs = {name: diagnose(urdf=urdf, data=train, validate=validate, **options).to_dict()
            for name, options in (("memory", {}), ("chunked", {"chunk_size": 2000}),
                                  ("budget", {"memory_budget": "1KB"}))}
    memory = runs["memory"]
    reasons = {(entry["spec"], tuple(entry["channels"])): entry["reason"] for entry in memory["rejected"]}
    for name in ("chunked", "budget"):
        streamed = runs[name]
        assert streamed["diagnosis_path"] == "streamed"
        found = _effects(streamed)
        # no finding the in-memory search refused as within its noise by the HAC test (main: spring on tau3 and
        # viscous[q4+q5] adopted streamed, refused in memory at Wald p = 0.4 and 0.03)
        refused = {key for key in found if reasons.get(key, "").startswith("not significant: its coefficients")}
        assert not refused, (name, refused)
        # every finding significant in the final fit (main: p = 0.12, 0.16 and 0.099 reported beside the findings)
        worst = max(entry["p_value"] for entry in streamed["effects"])
        assert worst < 1e-3 / 50, (name, worst)  # alpha over the candidates (more than 50 on this arm)
        # as many findings as in memory, within the shapes the streamed path holds fixed (main: 20 against 14)
        assert abs(len(found) - len(_effects(memory))) <= 2, (name, sorted(found), sorted(_effects(memory)))
        assert len(found & _effects(memory)) >= len(_effects(memory)) - 4, (name, sorted(found ^ _effects(memory)))
    assert _effects(runs["chunked"]) == _effects(runs["budget"])
