"""Records that cannot identify anything are refused with a message that names the problem, before any work:
a torque channel that holds one value throughout, and a validation file that is the training file."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from dynamics.measurements import Measurements
from estimation.data.segments import ConstantChannelError, check_varying_channels
from oed.cli import main


def test_a_constant_channel_is_named_with_its_value():
    t = np.arange(50) * 0.01
    varying = Measurements(t=t, q=np.column_stack([np.sin(t), np.cos(t)]),
                           tau=np.column_stack([np.sin(3 * t), np.full_like(t, 1.5)]))
    with pytest.raises(ConstantChannelError, match=r"training data: channel\(s\) tau2 = 1.5 hold one value"):
        check_varying_channels([varying], ["tau1", "tau2"], "training data")
    check_varying_channels([varying], ["tau1"], "training data")  # the varying channel passes
    # constant within each segment, varying over the record: it varies
    other = Measurements(t=t, q=varying.q, tau=np.column_stack([varying.tau[:, 0], np.full_like(t, 2.0)]))
    check_varying_channels([varying, other], ["tau1", "tau2"])


@pytest.fixture()
def record(tmp_path):
    t = np.arange(2000) * 0.005
    frame = pd.DataFrame({"t": t, "q1": np.sin(0.5 * t), "q2": 0.3 * np.cos(0.7 * t),
                          "tau1": np.sin(0.9 * t) + 0.01 * np.random.default_rng(0).normal(size=t.size),
                          "tau2": np.full_like(t, 1.5)})
    path = tmp_path / "train.csv"
    frame.to_csv(path, index=False)
    return path


def test_identify_refuses_a_constant_torque_channel(record, tmp_path, capsys):
    out = tmp_path / "result.json"
    code = main(["identify", "--robot", "puma560", "--joints", "2", "--data", str(record), "--out", str(out)])
    assert code == 2
    assert "channel(s) tau2 = 1.5 hold one value in every sample" in capsys.readouterr().err
    assert not out.exists()


def test_identify_refuses_a_validation_file_that_is_the_training_file(record, tmp_path, capsys):
    out = tmp_path / "result.json"
    code = main(["identify", "--robot", "puma560", "--joints", "2", "--data", str(record),
                 "--validate", str(tmp_path / "." / record.name), "--out", str(out)])
    assert code == 2
    message = capsys.readouterr().err
    assert "is also a --data file" in message
    assert "or leave out --validate: the choices are then made on held-out blocks of the training record" in message
    assert not out.exists()
