"""Rows of a robot at rest repeat on every channel (quantised encoders, a held torque command): they are kept
(interpolated back) and never make a hole, which is judged on the time stamps alone."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from estimation.data.loading import HoleError
from estimation.data.records import RepeatedRowsWarning, read_record


def position_only_log(rest_rows: int) -> pd.DataFrame:
    """A 1 kHz two-joint log, positions and torques only, quantised like a real drive, standing still for
    ``rest_rows`` rows in the middle (every channel repeats there), with regular time stamps throughout."""
    rate, n_samples, start = 1000.0, 3000, 1200
    t = np.arange(n_samples) / rate
    phase = np.concatenate([t[:start], np.full(rest_rows, t[start]), t[start] + t[1:n_samples - start - rest_rows + 1]])
    motion = np.column_stack([np.sin(2 * np.pi * 0.5 * phase), 0.5 * np.cos(2 * np.pi * 0.3 * phase)])  # stops, resumes
    q = np.round(motion / 1e-4) * 1e-4  # encoder counts
    tau = np.round((2.0 * motion + 0.3) / 1e-2) * 1e-2  # a quantised torque
    return pd.DataFrame({"t": t, "q1": q[:, 0], "q2": q[:, 1], "tau1": tau[:, 0], "tau2": tau[:, 1]})


@pytest.mark.parametrize("rest_rows", [88, 400])
def test_rows_at_rest_are_kept_and_make_no_hole(tmp_path, rest_rows):
    frame = position_only_log(rest_rows)
    path = tmp_path / "rest.csv"
    frame.to_csv(path, index=False)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        (segment,) = read_record(path, n_joints=2, split=False)  # a hole would raise HoleError here
    assert any(issubclass(item.category, RepeatedRowsWarning) for item in caught)
    assert segment.n_samples == frame.shape[0]
    np.testing.assert_allclose(segment.t, frame["t"].to_numpy(), atol=1e-12)
    # the rows at rest interpolated from the first row at rest to the first row moving again: the record as
    # logged to within one sample's motion (a stale packet and a rest are the same rows in a log)
    # every sample kept: tau1's quantised peak (0.01 N·m steps, held ~90 samples) is no clipped sensor
    # (estimation.data.log_cleaning.quantised_peak; h-streammask), so no sample is masked (NaN)
    for name, columns in (("q", ["q1", "q2"]), ("tau", ["tau1", "tau2"])):
        logged = frame[columns].to_numpy()
        one_step = np.max(np.abs(np.diff(logged, axis=0)), axis=0)
        read = getattr(segment, name)
        kept = ~np.isnan(read)
        assert np.all(kept), name
        assert np.all((np.abs(read - logged) <= one_step + 1e-12)[kept]), name


def test_a_hole_in_the_time_stamps_is_still_a_hole(tmp_path):
    frame = position_only_log(88).drop(index=range(2000, 2200))  # 0.2 s missing from the time column
    path = tmp_path / "hole.csv"
    frame.to_csv(path, index=False)
    with pytest.raises(HoleError, match="jumps by 0.201 s"), pytest.warns(RepeatedRowsWarning):
        read_record(path, n_joints=2, split=False)
