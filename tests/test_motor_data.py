"""The power-sign check of motor-side torques (estimation.data.motor_side): a gear ratio of the wrong sign
for the data is named, also when time stamps repeat, are missing, or velocities are recorded."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from dynamics.transmission import Transmission, TransmissionSignError
from estimation.data.loading import MeasurementError
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


def test_blank_motor_rows_are_a_loggers_dropouts_as_on_the_joint_side():
    """A row whose motor cells are all empty maps to an empty joint-side row, which the reader drops as a dropout
    (the real TX40's motor-side log with 0.5 % blank rows exited before); an empty cell beside written ones, text
    or inf is still refused."""
    from estimation.data.records import segments_from_frame

    frame = _frame()
    blank = [5, 200, 733]
    holed = frame.copy()
    holed.loc[blank, ["q1", "q2", "taum1", "taum2"]] = np.nan
    coupled = Transmission(np.array([[50.0, 0.0], [-30.0, -30.0]]))  # the second motor turns with both joints
    converted = joint_side_frame(holed, coupled, 2)
    assert converted.loc[blank, ["tau1", "tau2"]].isna().all().all()
    assert converted.drop(index=blank)[["tau1", "tau2"]].notna().all().all()
    expected = joint_side_frame(frame.drop(index=blank).reset_index(drop=True), coupled, 2)
    np.testing.assert_allclose(converted.drop(index=blank)[["tau1", "tau2"]].to_numpy(),
                               expected[["tau1", "tau2"]].to_numpy(), rtol=1e-12)
    with pytest.warns(UserWarning):
        (segment,) = segments_from_frame(converted, n_joints=2, model="internal", require=("q", "tau"))
    assert segment.metadata.get("resampled_from", segment.t.shape[0]) == frame.shape[0] - len(blank)
    for bad in (np.nan, np.inf, "n/a"):
        partial = frame.astype({"taum2": object}).copy()
        partial.loc[200, "taum2"] = bad
        with pytest.raises(MeasurementError, match="motor columns taum1..taum2 hold NaN/inf or text"):
            joint_side_frame(partial, coupled, 2)



def _read_alike(plain, other, warning, folder) -> None:
    """``other`` (the same motor-side record written otherwise) reads as ``plain``, with ``warning`` saying how,
    in memory and in the streamed path's joint-side copies."""
    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from estimation.data.motor_side import joint_side_copies, read_record_with_transmission

    model = build_model(load_robot("puma560", joints=2), "internal", "viscous")
    transmission = Transmission(np.diag(RATIOS))
    (expected,) = read_record_with_transmission(plain, model=model, transmission=transmission)
    with pytest.warns(warning):
        (segment,) = read_record_with_transmission(other, model=model, transmission=transmission)
    np.testing.assert_array_equal(segment.tau, expected.tau)
    np.testing.assert_array_equal(segment.q, expected.q)
    with pytest.warns(warning):
        (copy,) = joint_side_copies([other], folder / "copies", n_joints=2, transmission=transmission)
    (reference,) = joint_side_copies([plain], folder / "reference", n_joints=2, transmission=transmission)
    pd.testing.assert_frame_equal(pd.read_parquet(copy), pd.read_parquet(reference))


def test_a_units_row_beneath_a_motor_side_header_is_read_as_on_the_joint_side(tmp_path):
    """A second line naming the SI units under a motor-side file's header is skipped, as under a joint-side one
    (the real TX40's log with such a line exited before: its text was read as motor values), in memory and in the
    streamed path's joint-side copies."""
    from estimation.data.loading import UnitsRowWarning

    frame = _frame()
    plain, with_units = tmp_path / "plain.csv", tmp_path / "units.csv"
    frame.to_csv(plain, index=False)
    with with_units.open("w") as stream:
        stream.write(",".join(frame.columns) + "\ns,rad,rad,N m,N m\n")
        frame.to_csv(stream, index=False, header=False)
    _read_alike(plain, with_units, UnitsRowWarning, tmp_path)


def test_a_semicolon_separated_motor_side_file_is_read_as_a_joint_side_one(tmp_path):
    """A spreadsheet's European export (';' between columns, ',' the decimal mark) with motor-side columns: its
    motor columns found and converted, in memory and in the streamed path's copies, as the comma-separated file."""
    from estimation.data.loading import DelimiterWarning

    frame = _frame()
    plain, european = tmp_path / "plain.csv", tmp_path / "european.csv"
    frame.to_csv(plain, index=False, float_format="%.12g")
    frame.to_csv(european, index=False, sep=";", decimal=",", float_format="%.12g")
    _read_alike(plain, european, DelimiterWarning, tmp_path)
