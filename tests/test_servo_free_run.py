"""oed servo-fit holds the linear servo model to the angle noise: a joint whose drive saturates at its rated speed
drifts in free run far beyond the noise, and the fit says so, naming the joint; a linear drive does not."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from dynamics.simulation.servo_simulator import simulate_servo_arm
from estimation.servo.free_run_check import FREE_RUN_LIMIT, check_free_run
from oed.cli import main


def test_the_yardstick_is_the_larger_noise_and_the_limit_decides():
    rng = np.random.default_rng(0)
    angles = np.sin(np.linspace(0, 20, 2000)) + 0.01 * rng.normal(size=2000)  # white noise: differences read 0.01
    check = check_free_run(2, angles, rmse_free_run=0.03, rmse_one_step=0.004)
    assert check.method == "differences" and check.noise_std == pytest.approx(0.01, rel=0.1)
    assert check.described and check.warning() is None
    check = check_free_run(2, angles, rmse_free_run=0.3, rmse_one_step=0.02)  # the one-step error is larger
    assert check.method == "one-step" and check.ratio == pytest.approx(15)
    assert not check.described and check.warning().startswith("joint 2: the free-run error is 15 times")
    assert FREE_RUN_LIMIT == 5.0


@pytest.mark.parametrize("max_speed, warned", [(5.2, True), (1e6, False)])
def test_servo_fit_warns_on_a_drive_that_saturates(tmp_path, capsys, max_speed, warned):
    assert main(["aprbs", "--joints", "4", "--duration", "40", "--dt", "0.01", "--seed", "1",
                 "--out", str(tmp_path / "aprbs.csv")]) == 0
    aprbs = pd.read_csv(tmp_path / "aprbs.csv")
    t, u = aprbs["t"].to_numpy(), aprbs[[f"u{j}" for j in range(1, 5)]].to_numpy()
    q = simulate_servo_arm(t, u, max_speed=max_speed).q
    frame = aprbs.assign(**{f"q{j + 1}": q[:, j] for j in range(4)})
    frame.to_csv(tmp_path / "servo.csv", index=False)
    out = tmp_path / "fit.json"
    code = main(["servo-fit", "--data", str(tmp_path / "servo.csv"), "--dt", "0.01", "--out", str(out)])
    error = capsys.readouterr().err
    assert code == 0, error
    document = json.loads(out.read_text())
    ratios = [joint["free_run_check"]["free_run_over_noise"] for joint in document["joints"].values()]
    if warned:
        assert all(ratio > 3 * FREE_RUN_LIMIT / 2 for ratio in ratios), ratios
        assert "joint 1: the free-run error is" in error and "does not describe this joint" in error
        assert len(document["warnings"]) == 4
    else:
        assert all(ratio < FREE_RUN_LIMIT for ratio in ratios), ratios
        assert document["warnings"] == [] and "free-run error" not in error
