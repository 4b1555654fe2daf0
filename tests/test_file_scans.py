"""A streamed run scans each file once and hands the scan to its later passes (h-scanonce): the run's
:class:`~estimation.streaming.chunks.FileScans`, an explicit object, no process-wide store. A pass given the scan
of an earlier pass reads the file once instead of three times (the scan, the clipped sensors' pass, its own) and
gives the same chunks, bit for bit; the time base's findings are said by the pass that scans."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot


@pytest.fixture
def jittered(tmp_path):
    """A 2-joint log with jittered stamps, a re-sent row and a clipped torque (resampled, rows dropped, masked)."""
    generator = np.random.default_rng(3)
    n = 400
    t = np.arange(n) * 0.005 + generator.uniform(-0.001, 0.001, n)
    q = np.column_stack([np.sin(3 * t), np.cos(2 * t)])
    tau = np.column_stack([np.sin(t) + 0.01 * generator.standard_normal(n), np.clip(np.cos(4 * t), -0.9, 0.9)])
    frame = pd.DataFrame({"t": t, "q1": q[:, 0], "q2": q[:, 1], "tau1": tau[:, 0], "tau2": tau[:, 1]})
    frame.loc[200, ["q1", "q2", "tau1", "tau2"]] = frame.loc[199, ["q1", "q2", "tau1", "tau2"]].to_numpy()
    frame.to_csv(tmp_path / "run.csv", index=False, float_format="%.17g")
    return tmp_path / "run.csv"


def _counted(monkeypatch):
    import estimation.streaming.chunks as chunks

    calls = []
    scan_time = chunks.scan_time

    def counted(*args, **kwargs):
        calls.append(args[1])
        return scan_time(*args, **kwargs)

    monkeypatch.setattr(chunks, "scan_time", counted)
    return calls


def _same(first, second):
    assert len(first) == len(second)
    for a, b in zip(first, second):
        for name in ("t", "q", "dq", "ddq", "tau"):
            x, y = getattr(a, name), getattr(b, name)
            assert (x is None) == (y is None)
            if x is not None:
                assert x.tobytes() == y.tobytes(), name


def test_later_passes_take_the_first_pass_scan_and_give_the_same_chunks(jittered, monkeypatch):
    from estimation.streaming.chunks import FileScans, logged_chunks, read_chunks

    model = build_model(load_robot("puma560", joints=2), "internal", "viscous,coulomb,offset")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        alone = list(read_chunks(jittered, model, chunk_size=128))
        logged_alone = list(logged_chunks(jittered, model, chunk_size=128))
    calls = _counted(monkeypatch)
    scans = FileScans()
    with pytest.warns(UserWarning) as said:
        first = list(read_chunks(jittered, model, chunk_size=128, scans=scans))
    assert len(calls) == 1 and said  # the first pass scans and says the file's findings
    with warnings.catch_warnings(record=True) as again:
        warnings.simplefilter("always")
        second = list(read_chunks(jittered, model, chunk_size=128, scans=scans))
        logged = list(logged_chunks(jittered, model, chunk_size=128, scans=scans))
    assert len(calls) == 1  # the later passes took it
    assert not any("irregular sampling" in str(warning.message) for warning in again)  # the findings said once
    _same(alone, first)
    _same(alone, second)
    _same(logged_alone, logged)
    assert first[0].metadata.get("resampled_from") is not None  # the jittered stamps resampled
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        other = build_model(load_robot("puma560", joints=2), "internal", "viscous")
        list(read_chunks(jittered, model, chunk_size=100, scans=scans))  # another block size: scanned anew
        list(read_chunks(jittered, other, chunk_size=128, scans=scans))  # another model: scanned anew
    assert len(calls) == 3


def test_a_logged_pass_holds_its_scan_for_logged_passes_not_for_a_pass_that_says_the_findings(jittered, monkeypatch):
    from estimation.streaming.chunks import FileScans, logged_chunks, read_chunks

    model = build_model(load_robot("puma560", joints=2), "internal", "viscous,coulomb,offset")
    calls = _counted(monkeypatch)
    scans = FileScans()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        first = list(logged_chunks(jittered, model, chunk_size=128, scans=scans))
        second = list(logged_chunks(jittered, model, chunk_size=128, scans=scans))
    assert len(calls) == 1
    _same(first, second)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        list(read_chunks(jittered, model, chunk_size=128, scans=scans))
    assert len(calls) == 2  # its findings said: scanned anew
    assert any("irregular sampling" in str(warning.message) for warning in said)
