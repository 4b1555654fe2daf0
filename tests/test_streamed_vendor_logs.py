"""Controllers' and drivers' logs read by the streamed reader as in memory (estimation.data.vendor_logs through
estimation.data.records.in_the_format, applied block by block by estimation.streaming.chunks).

- cheap: a libfranka robot-state log and a KUKA FRI ``LBRState`` export (arrays in cells) read in blocks give the
  in-memory reader's samples bit for bit, its reading said once; a UR RTDE log whose only torques are commanded is
  refused streamed with the in-memory error, word for word (a commanded torque is never the measured one);
- slow: ``oed identify`` with ``--chunk-size`` on UR RTDE's currents (through ``--transmission``, read from
  joint-side copies made block by block) and on KUKA FRI's arrays in cells gives memory's answer: the same
  derivatives, parameters to 1e-8 relative to the largest (measured 2.5e-10 on the Fourier path's sums, 8e-15 on
  FRI), the validation errors alike, and ``oed predict`` streamed on the test record memory's errors (libfranka's
  names: the cheap reader test; its verbs measured 2.5e-10 alike, benchmarks/README.md).
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from estimation.data.loading import MissingColumnError
from estimation.data.records import read_record
from estimation.data.vendor_logs import VendorColumnsWarning
from estimation.streaming.chunks import read_chunks
from tests.test_vendor_logs import CURRENT_TO_TORQUE, lbr_state, libfranka, rtde, signals

#: streamed against memory: the same samples, sums in another order (the Fourier path's: 2.5e-10 measured)
SAME = 1e-8


def _said(caught) -> list[str]:
    return [str(item.message) for item in caught if issubclass(item.category, VendorColumnsWarning)]


@pytest.mark.parametrize("writer", [libfranka, lbr_state], ids=["libfranka", "kuka-fri"])
def test_a_controllers_log_read_in_blocks_is_memory_s_bit_for_bit(writer, tmp_path):
    model = build_model(load_robot("puma560"), "internal")
    path = tmp_path / "log.csv"
    writer(signals(6, rows=1500), n=6).to_csv(path, index=False, float_format="%.12g")
    with warnings.catch_warnings(record=True) as in_memory:
        warnings.simplefilter("always")
        (whole,) = read_record(path, model=model)
    with warnings.catch_warnings(record=True) as streamed:
        warnings.simplefilter("always")
        blocks = list(read_chunks(path, model, chunk_size=400))
    assert len(blocks) > 1 and _said(streamed) == _said(in_memory) and len(_said(streamed)) == 1
    whole = whole.as_recorded
    for name in ("t", "q", "tau"):
        assert np.array_equal(np.concatenate([getattr(block.as_recorded, name) for block in blocks]),
                              getattr(whole, name)), name
    if whole.dq is not None:
        assert np.array_equal(np.concatenate([block.as_recorded.dq for block in blocks]), whole.dq)


def test_a_commanded_torque_alone_is_refused_streamed_as_in_memory(tmp_path):
    model = build_model(load_robot("puma560"), "internal")
    path = tmp_path / "rtde.csv"
    rtde(signals(6, rows=600)).drop(columns=[f"{name}_{j}" for name in ("actual_current", "target_current")
                                             for j in range(6)]).to_csv(path, index=False, float_format="%.12g")
    with pytest.raises(MissingColumnError) as in_memory, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        read_record(path, model=model)
    with pytest.raises(MissingColumnError) as streamed, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        list(read_chunks(path, model, chunk_size=200))
    assert str(streamed.value) == str(in_memory.value) and "target_moment_0" in str(streamed.value)


def _records(folder, kind: str) -> dict:
    from dynamics.simulation.synthetic import simulate
    from oed.fourier import random_fourier

    model = build_model(load_robot("puma560"), "internal", "viscous")
    theta = model.nominal_parameters(viscous=[4.0, 4.0, 3.0, 1.0, 1.0, 1.0])
    files = {}
    for role, seed in (("train", 1), ("validate", 2), ("test", 3)):
        trajectory = random_fourier(model.robot, seed=seed, frequency_hz=0.25)
        clean = simulate(model, theta, trajectory, rate_hz=200.0)
        noise = {f"tau{j + 1}": 0.02 * span for j, span in enumerate(np.ptp(clean.tau, axis=0))}
        frame = simulate(model, theta, trajectory, rate_hz=200.0, periods=2, noise=noise, seed=10 + seed).to_frame()
        values = {column: frame[column].to_numpy() for column in frame.columns}
        table = rtde(values) if kind == "rtde" else libfranka(values, n=6) if kind == "libfranka" else \
            lbr_state(values, n=6)
        files[role] = folder / f"{role}.csv"
        table.to_csv(files[role], index=False, float_format="%.12g")
    return files


@pytest.mark.slow  # oed identify in memory and streamed, two predictions, on a 6-joint arm (RTDE 55 s, FRI 130 s)
@pytest.mark.parametrize("kind", ["rtde", "kuka-fri"])
def test_identify_streamed_reads_a_controllers_log_as_memory_does(kind, tmp_path):
    from oed.cli import main

    files = _records(tmp_path, kind)
    options = ["--robot", "puma560", "--friction", "viscous"]
    if kind == "rtde":
        (tmp_path / "transmission.json").write_text(json.dumps({"ratios": [1.0] * 6,
                                                                "torque_constants": list(CURRENT_TO_TORQUE)}))
        options += ["--transmission", str(tmp_path / "transmission.json")]
    results, tests = {}, {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name, extra in (("memory", []), ("streamed", ["--chunk-size", "400"])):
            out = tmp_path / f"{name}.json"
            assert main(["identify", *options, "--data", str(files["train"]), "--validate", str(files["validate"]),
                         "--out", str(out), "--quiet", *extra]) == 0
            results[name] = json.loads(out.read_text())
            metrics = tmp_path / f"{name}-test.json"
            assert main(["predict", "--model", str(out), "--data", str(files["test"]), "--metrics", str(metrics),
                         *extra]) == 0
            tests[name] = json.loads(metrics.read_text())
    memory, streamed = results["memory"], results["streamed"]
    assert streamed["not_computed"] and tests["streamed"]["prediction_path"] == "streamed"
    assert memory["preprocessing"]["method"] == streamed["preprocessing"]["method"]
    mine, theirs = np.array(memory["model_file"]["theta"]), np.array(streamed["model_file"]["theta"])
    assert np.max(np.abs(mine - theirs)) <= SAME * np.max(np.abs(mine))
    for channel, value in memory["validation"]["mse"].items():
        assert streamed["validation"]["mse"][channel] == pytest.approx(value, rel=SAME), channel
        assert tests["streamed"]["mse"][channel] == pytest.approx(tests["memory"]["mse"][channel], rel=SAME), channel
    assert streamed.get("warnings") == memory.get("warnings")  # the reader's findings said, not stored, alike
