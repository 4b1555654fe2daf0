"""Logs as they come, the cases h-logs2 and h-unseen16 left open (h-logs3): a log written newest first, ABB EGM's
``header.tm`` as its only clock, torques held at a lower rate than the positions (each value repeated on the rows
between two samples), a MuJoCo servo's force computed from its controls and the state with the MJCF given."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from tests.test_unseen_robots import FRICTION, Log, truth, urdf_of, write_record


@pytest.fixture(scope="module")
def puma3(tmp_path_factory):
    """A PUMA's first three joints, one clean 2 s record at 250 Hz (no velocity column) and its model."""
    folder = tmp_path_factory.mktemp("puma3")
    urdf = urdf_of("puma560:3", folder)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    write_record(model, truth(model), Log(2.0, 250.0, velocity=False), 11, folder / "clean.csv")
    return model, folder / "clean.csv"


def read_quietly(path, model):
    from estimation.data.records import read_measurements

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        read = read_measurements(path, model=model)
    return read, [str(warning.message) for warning in caught], [warning.category for warning in caught]


def test_a_log_written_newest_first_is_read_reversed_and_said(puma3, tmp_path):
    """Every time step negative (a ring buffer dumped from its latest entry): read reversed, equal to the same log
    oldest first, in a ``NewestFirstWarning``; at 6d10335 it was refused ("decreases … sort the samples"). Rows out of
    order (shuffled) stay an error naming the rows; the streamed reader (chunk by chunk) refuses the newest-first log
    naming the in-memory reader that reads it."""
    from estimation.data import NewestFirstWarning, TimeBaseError
    from estimation.data.records import read_measurements
    from estimation.streaming.chunks import segment_sources

    model, clean = puma3
    table = pd.read_csv(clean)
    table.iloc[::-1].to_csv(tmp_path / "newest_first.csv", index=False, float_format="%.17g")
    expected, _, _ = read_quietly(clean, model)
    read, said, kinds = read_quietly(tmp_path / "newest_first.csv", model)
    assert NewestFirstWarning in kinds, said
    assert any("written newest first, read reversed" in message for message in said), said
    for name in ("t", "q", "tau"):
        assert np.array_equal(getattr(read, name), getattr(expected, name)), name
    shuffled = table.sample(frac=1.0, random_state=3)
    shuffled.to_csv(tmp_path / "shuffled.csv", index=False)
    rows = np.flatnonzero(np.diff(shuffled["t"].to_numpy()) < 0)
    with pytest.raises(TimeBaseError, match=rf"decreases at row {rows[0] + 1} .* other row\(s\): {rows[1] + 1} \(.*"
                                            r"rows out of order \(neither oldest nor newest first\); sort the samples"):
        read_measurements(tmp_path / "shuffled.csv", model=model)
    with pytest.raises(TimeBaseError, match="a log written newest first; the in-memory reader reads it reversed"):
        segment_sources([tmp_path / "newest_first.csv"], model, chunk_size=100)


def test_abb_egm_header_tm_alone_is_read_as_milliseconds(tmp_path):
    """An EGM table whose only clock is the message header's ``tm`` (egm.proto: milliseconds; no ``EgmClock``
    ``feedBack.time``): read as the time in seconds, said with the map that reads it so (which reads the same
    values). At 6d10335 it was refused: "missing column(s) t". A plan's header (``planned.header.tm``) is no clock of
    the samples."""
    from dynamics.robots import load_robot
    from estimation.data import MissingColumnError
    from tests.test_vendor_logs import abb_egm, read_file, said_map, signals

    values = signals(6, rows=200)
    robot = load_robot("puma560", joints=6)
    table = abb_egm(values).drop(columns=["feedBack.time.sec", "feedBack.time.usec", "planned.time.sec",
                                          "planned.time.usec"])
    table["header.tm"] += 7_200_000  # two hours since the controller started
    read, said = read_file(table, tmp_path / "egm.csv", robot)
    assert np.allclose(read.t, values["t"] + 7200.0, atol=1e-9) and np.allclose(read.tau[:, 2], values["tau3"])
    assert any("ABB EGM's header stamp header.tm, milliseconds by its protocol (--columns 't=0.001*header.tm')"
               in message for message in said), said
    mapped, _ = read_file(table, tmp_path / "egm.csv", robot, columns=said_map(said, "controller's log"))
    assert np.array_equal(mapped.t, read.t) and np.array_equal(mapped.q, read.q)
    with pytest.raises(MissingColumnError, match="missing column"):
        read_file(table.rename(columns={"header.tm": "planned.header.tm"}), tmp_path / "plan.csv", robot)
