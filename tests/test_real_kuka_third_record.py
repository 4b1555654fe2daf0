"""Real data: the KUKA LWR4+ runs of FloBaRoID (../shared/data/kuka_lwr4). The model `oed diagnose` chooses from
the first two records, used on the third, against a plain least-squares fit of rigid body, viscous and Coulomb
friction and offsets from the same records.

Run 2 repeats run 1's trajectory (positions within 0.4 % of their spread, sample by sample); run 3 moves twice
as fast. The held-out confirmation on run 2 therefore cannot reject an effect fitted to run 1's own motion:
`oed diagnose` and `oed identify` say so. The diagnosis's model predicts run 3 better in total than plain least
squares, not on every joint (a strict xfail with the measured figures).
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from estimation.datasets.kuka import load_kuka_run
from estimation.identification.repeated_motion import REPEAT_FRACTION, repeated_motion
from oed.cli import main
from tests.conftest import shared_data

pytestmark = pytest.mark.realdata


@pytest.fixture(scope="module")
def runs():
    folder = shared_data("kuka_lwr4")
    return folder, [load_kuka_run(folder / f"kuka_lwr4_HW_measurements_{index}.npz") for index in (1, 2, 3)]


def test_run_2_repeats_run_1_and_run_3_does_not(runs):
    _, (first, second, third) = runs
    assert repeated_motion(first, second) < 0.01
    assert repeated_motion(first, third) > 10 * REPEAT_FRACTION


def _parquet(run, path):
    table = {"t": run.t}
    for name, values in (("q", run.q), ("dq", run.dq), ("ddq", run.ddq), ("tau", run.tau)):
        table.update({f"{name}{j + 1}": values[:, j] for j in range(values.shape[1])})
    pd.DataFrame(table).to_parquet(path)
    return str(path)


def _run3_mse(model, record, folder):
    metrics = folder / "metrics.json"
    assert main(["predict", "--model", str(model), "--data", record, "--metrics", str(metrics)]) == 0
    return np.array(list(json.loads(metrics.read_text())["mse"].values()))


@pytest.fixture(scope="module")
def third_record_errors(runs, tmp_path_factory):
    """Run 3's MSE per joint: the diagnosis's model (run 1, validated on run 2) and plain least squares."""
    folder, records = runs
    tmp_path = tmp_path_factory.mktemp("third_record")
    paths = [_parquet(run, tmp_path / f"run{index}.parquet") for index, run in enumerate(records, start=1)]
    urdf = str(folder / "kuka_lwr4.urdf")
    report, plain = tmp_path / "report.json", tmp_path / "plain.json"
    assert main(["diagnose", "--urdf", urdf, "--data", paths[0], "--validate", paths[1], "--out", str(report)]) == 0
    selection = json.loads(report.read_text())["model_selection"]
    assert (selection["chosen"], selection["selection"]) == ("consistent", "repeated-motion")
    assert main(["identify", "--urdf", urdf, "--data", paths[0], "--validate", paths[1], "--friction",
                 "viscous,coulomb,offset", "--method", "ols", "--out", str(plain)]) == 0
    diagnosed, least_squares = _run3_mse(report, paths[2], tmp_path), _run3_mse(plain, paths[2], tmp_path)
    print(f"\nrun 3 MSE per joint, diagnosis: {np.round(diagnosed, 3)} (total {diagnosed.sum():.3f}); "
          f"plain least squares: {np.round(least_squares, 3)} (total {least_squares.sum():.3f})")
    return diagnosed, least_squares


@pytest.mark.slow
def test_the_diagnosed_model_predicts_the_third_record_as_well_as_plain_least_squares(third_record_errors):
    # measured: the default answer (the consistent refit) 1.90 N²m² in total against 7.99; the adopted model as
    # fitted 7.20
    diagnosed, least_squares = third_record_errors
    assert diagnosed.sum() <= least_squares.sum()


@pytest.mark.slow
# measured: run 3 MSE per joint of the diagnosis's adopted model as fitted 1.468 1.525 0.541 1.725 1.272 0.494 0.174
# (7.20 N²m²; worse than plain least squares on joints 1 and 5, an xfail before); since run 2 repeats run 1's motion
# the default answer is its consistent refit (model_selection): 1.289 0.104 0.099 0.168 0.150 0.047 0.046 (1.90);
# with the plain law completed on the repeat (h-kukaj1): 0.530 0.096 0.096 0.226 0.155 0.087 0.030 (1.22),
# against plain ordinary least squares 1.341 1.918 0.775 1.990 0.984 0.590 0.391 (7.99)
def test_the_diagnosed_model_is_as_good_on_every_joint_of_the_third_record(third_record_errors):
    diagnosed, least_squares = third_record_errors
    assert np.all(diagnosed <= least_squares)
