"""The main job runs end to end and finds the undeclared effects on the right joints."""

from __future__ import annotations

import json


def test_demo_loop_finds_coulomb_friction_and_cuts_the_validation_error(tmp_path):
    from oed.demo import run_demo

    lines = []
    document = run_demo(tmp_path, say=lines.append)
    found = {(effect["spec"], tuple(effect["channels"])) for effect in document["effects"]}
    assert {("coulomb:tanh", ("tau1",)), ("coulomb:tanh", ("tau2",)), ("coulomb:tanh", ("tau3",))} <= found
    assert {spec for spec, _ in found} <= {"coulomb:tanh", "offset"}, found
    before, after = document["validation"]["before"]["mse"], document["validation"]["after"]["mse"]
    assert all(after[channel] < 0.2 * before[channel] for channel in before)
    # the targets: every joint within 1.5x the torque-noise variance, every estimate within 3 σ
    assert all(after[channel] < 1.5 * 0.2**2 for channel in after), after
    truth = document["truth"]
    for effect in document["effects"]:
        pairs = list(zip(effect["parameters"], effect["values"], effect["std"]))
        pairs += [(name, value, effect["shape_std"][name]) for name, value in effect["shape"].items()]
        for name, value, std in pairs:
            assert abs(value - truth[name]) < 3 * std, (name, value, std, truth[name])
    assert any("σ)" in line for line in lines) and any("as recorded" in line for line in lines)
    assert json.loads((tmp_path / "report.json").read_text())["effects"]
    assert (tmp_path / "report.md").exists() and (tmp_path / "validation.png").exists()


def test_demo_into_a_file_path_is_a_clear_error(tmp_path, capsys):
    from oed.cli import main

    target = tmp_path / "out"
    target.write_text("a file")
    assert main(["demo", "--out", str(target)]) == 2
    assert "is a file: the demo writes its report and figures into a folder" in capsys.readouterr().err


def test_a_failing_demo_leaves_none_of_its_files(tmp_path, monkeypatch):
    """The trajectories of step 1 used to stay behind when a later step failed (and the folder made for them)."""
    import pytest

    from dynamics.simulation.simulator import Simulator
    from oed.demo import run_demo

    def broken(*args, **kwargs):
        raise RuntimeError("simulation failed")

    monkeypatch.setattr(Simulator, "run", broken)
    with pytest.raises(RuntimeError, match="simulation failed"):
        run_demo(tmp_path / "demo", say=lambda _: None)
    assert not (tmp_path / "demo").exists(), "nor the folder it made for them"
