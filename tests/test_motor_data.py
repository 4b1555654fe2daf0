"""The power-sign check of motor-side torques (estimation.data.motor_side): a gear ratio of the wrong sign
for the data is named, also when time stamps repeat, are missing, or velocities are recorded."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from dynamics.transmission import Transmission, TransmissionSignError
from estimation.data.motor_side import joint_side_frame

RATIOS = np.array([50.0, -30.0])


def _frame(*, stamps: str = "unique", with_dq: bool = False) -> pd.DataFrame:
    t = np.linspace(0.0, 10.0, 1001)
    q = np.column_stack([np.sin(t), 0.5 * np.sin(2 * t)])
    dq = np.column_stack([np.cos(t), np.cos(2 * t)])
    tau = 0.5 * np.sign(dq) + 0.2 * dq  # joint-side torques that dissipate
    tau_m = np.linalg.solve(np.diag(RATIOS).T, tau.T).T  # what the motors give: tau = R^T tau_m
    frame = pd.DataFrame({"t": t, "q1": q[:, 0], "q2": q[:, 1], "taum1": tau_m[:, 0], "taum2": tau_m[:, 1]})
    if with_dq:
        frame["dq1"], frame["dq2"] = dq[:, 0], dq[:, 1]
    if stamps == "repeated":  # a logger that writes some samples twice
        frame = pd.concat([frame, frame.iloc[::7]]).sort_values("t", kind="stable").reset_index(drop=True)
    elif stamps == "none":
        frame = frame.drop(columns="t")
    return frame


@pytest.mark.parametrize("stamps, with_dq", [("unique", False), ("repeated", False), ("none", False), ("unique", True)])
def test_a_ratio_of_the_wrong_sign_for_the_data_is_named(stamps, with_dq):
    frame = _frame(stamps=stamps, with_dq=with_dq)
    converted = joint_side_frame(frame, Transmission(np.diag(RATIOS)), 2)  # the right ratios: accepted
    assert {"tau1", "tau2"} <= set(converted.columns)
    wrong = Transmission(np.diag(RATIOS * np.array([1.0, -1.0])))
    with pytest.raises(TransmissionSignError, match="joint 2"):
        joint_side_frame(frame, wrong, 2)
