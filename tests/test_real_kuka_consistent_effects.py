"""Real data: the consistent refit of the KUKA LWR4+ diagnosis (../shared/data/kuka_lwr4, skipped when absent).

Diagnosed on run 1 from the declared viscous model (candidates as `oed diagnose`), confirmed on run 2; the
consistent refit of the adopted model (its shaped laws at their fitted shapes, its delay), the prior's weight
chosen on run 2, predicts run 3, which no choice saw, no worse than the consistent fit of the declared model
(benchmarks/bench_consistent_effects.py has the table).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.consistent.identification import consistent_fit, consistent_refit
from estimation.datasets.kuka import load_kuka_run
from estimation.diagnosis.candidates.coupling import coupling_candidates
from estimation.diagnosis.search import default_candidates, diagnose
from estimation.identification.fit import ImplausibleEstimateWarning
from tests.conftest import shared_data

pytestmark = [pytest.mark.realdata, pytest.mark.slow]


def test_consistent_refit_with_the_diagnosed_effects_predicts_run_3_no_worse_than_without():
    folder = shared_data("kuka_lwr4")
    robot = load_robot(urdf=folder / "kuka_lwr4.urdf")
    train, validate, test = (load_kuka_run(folder / f"kuka_lwr4_HW_measurements_{index}.npz") for index in (1, 2, 3))
    declared = build_model(robot, "internal", "viscous")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ImplausibleEstimateWarning)
        candidates = default_candidates(declared) + coupling_candidates(declared, None, train=train)
        diagnosis = diagnose(declared, train, validate, candidates=candidates)
        without = consistent_fit(diagnosis.before, train, validate)
        with_effects = consistent_refit(diagnosis, train, validate)
    assert diagnosis.effects, "the diagnosis adopts effects on the KUKA"
    estimate = with_effects.estimate
    assert np.all(estimate.margins > 0)
    assert all(value >= 0 for name, value in estimate.effect_values().items() if name.startswith(("fv", "fc")))
    before = np.array(list(without.compare(test).mse.values()))
    after = np.array(list(with_effects.compare(test).mse.values()))
    print(f"\nKUKA run 3 MSE per joint, consistent: declared {np.round(before, 3)}, diagnosed {np.round(after, 3)}")
    assert after.sum() <= before.sum()
    assert np.all(after <= 1.1 * before), (before, after)
