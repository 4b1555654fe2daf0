"""The main job runs end to end and finds the undeclared effects on the right joints."""

from __future__ import annotations

import json


def test_demo_loop_finds_coulomb_friction_and_cuts_the_validation_error(tmp_path):
    from oed.demo import run_demo

    document = run_demo(tmp_path, say=lambda _: None)
    found = {(effect["name"], tuple(effect["channels"])) for effect in document["effects"]}
    assert {("coulomb", ("tau1",)), ("coulomb", ("tau2",)), ("coulomb", ("tau3",))} <= found
    before, after = document["validation"]["before"]["mse"], document["validation"]["after"]["mse"]
    assert all(after[channel] < 0.2 * before[channel] for channel in before)
    assert json.loads((tmp_path / "report.json").read_text())["effects"]
    assert (tmp_path / "report.md").exists() and (tmp_path / "validation.png").exists()
