"""Passive joints read by the streamed path: ``oed identify`` and ``oed diagnose`` with ``--chunk-size`` give
memory's answer (h-passive's cases, tests/passive_simulation.py).

- a PUMA 3 whose third joint is free (``--passive 3``, the log without ``tau3``): both verbs streamed and in memory
  choose the same derivatives, model and effects; the parameters, the validation errors and ``oed predict``'s errors
  on the test record (a motion no choice saw) agree to rounding (measured: parameters 2e-13 apart relative to the
  largest, errors 1e-10 relative, the passive channel's 9e-10 of its 6e-6 N²m²); the result and the model file name
  the passive joint alike;
- a Pendubot whose URDF declares a motor on the shoulder only: the elbow read as passive from the description on the
  streamed path too, ``oed identify``'s answer memory's.

The standard deviations are not compared: streamed they are batch means (``not_computed.hac_lags``), as on every
streamed run.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from oed.cli import main
from tests.passive_simulation import write_passive_records
from tests.test_passive_joints import CASES, PENDUBOT

#: streamed against memory: the same samples, the filter's chunk margins (7e-12 on the errors) carried by the fits
SAME = 1e-8
CHUNK = "500"


def _run(verb: str, urdf, files, out, *options: str) -> dict:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main([verb, "--urdf", str(urdf), "--data", str(files["train"]), "--validate", str(files["validate"]),
                     "--out", str(out), "--quiet", *options]) == 0
        assert main(["predict", "--model", str(out), "--data", str(files["test"]), "--metrics",
                     str(out.with_suffix(".test.json"))]) == 0
    return {"result": json.loads(out.read_text()), "test": json.loads(out.with_suffix(".test.json").read_text())}


def _assert_alike(memory: dict, streamed: dict) -> None:
    left, right = memory["result"], streamed["result"]
    assert right["not_computed"] and not left.get("not_computed")  # the streamed path took it
    assert left["passive_joints"]["joints"] == right["passive_joints"]["joints"]
    assert left["model_file"]["robot"].get("passive") == right["model_file"]["robot"].get("passive")
    assert left["preprocessing"]["cutoff_hz"] == right["preprocessing"]["cutoff_hz"]
    assert left["model_file"]["chosen"] == right["model_file"]["chosen"]
    for key in ("theta",):
        mine, theirs = np.array(left["model_file"][key]), np.array(right["model_file"][key])
        assert np.max(np.abs(mine - theirs)) <= SAME * np.max(np.abs(mine)), key
    for channel, value in memory["test"]["mse"].items():
        assert streamed["test"]["mse"][channel] == pytest.approx(value, rel=SAME), channel


@pytest.mark.slow  # two verbs, each in memory and streamed, on a 3-joint arm (about 30 s)
def test_a_free_elbow_named_with_the_option_is_read_streamed_as_in_memory(tmp_path):
    urdf, _, files, _ = write_passive_records(CASES["puma3"], tmp_path)
    for verb in ("identify", "diagnose"):
        memory = _run(verb, urdf, files, tmp_path / f"{verb}-memory.json", "--passive", "3")
        streamed = _run(verb, urdf, files, tmp_path / f"{verb}-streamed.json", "--passive", "3", "--chunk-size", CHUNK)
        assert memory["result"]["passive_joints"]["joints"] == ["joint3"]
        _assert_alike(memory, streamed)
        if verb == "diagnose":
            effects = [(effect["name"], effect["channels"]) for effect in memory["result"]["effects"]]
            assert [(effect["name"], effect["channels"]) for effect in streamed["result"]["effects"]] == effects
            for mine, theirs in zip(memory["result"]["effects"], streamed["result"]["effects"]):
                assert theirs["values"] == pytest.approx(mine["values"], rel=SAME), mine["name"]


@pytest.mark.slow  # oed identify in memory and streamed on a 2-joint arm (about 10 s)
def test_a_free_elbow_the_description_gives_is_read_streamed_as_in_memory(tmp_path):
    urdf, _, files, _ = write_passive_records(CASES["pendubot"], tmp_path, urdf_text=PENDUBOT)
    memory = _run("identify", urdf, files, tmp_path / "memory.json")
    streamed = _run("identify", urdf, files, tmp_path / "streamed.json", "--chunk-size", CHUNK)
    assert streamed["result"]["passive_joints"]["described"] == memory["result"]["passive_joints"]["described"] \
        == ["elbow"]
    _assert_alike(memory, streamed)
