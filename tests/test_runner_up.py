"""The diagnosis's runner-up (the best rival model it did not choose, kept in report.json with its fit and model
file) and ``oed design --from report.json --discriminate`` against it: end to end on a simulated PUMA whose
joint 2 has a Stribeck law, in memory and streamed, and the bad input of the discriminating route."""

from __future__ import annotations

import json

import numpy as np
import pytest

from benchmarks.sequential_case import StribeckCase
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from dynamics.effects.linear import CoulombFriction, JointOffset
from estimation.diagnosis.runner_up import (NOTHING_TRIED, Alternative, LastMove, RivalAhead, RunnerUpOutcome, bic_gap,
                                            fit_runner_up, in_memory_fitter)
from estimation.estimators.effect_blocks import Block, ShapeSearchError
from estimation.diagnosis.search import diagnose
from estimation.identification.fit import identify
from estimation.identification.identified_model import IdentifiedModel
from estimation.identification.model_file import ModelFile, RobotSource, model_file_document
from estimation.preprocessing.plan import Preprocessing
from oed.cli import main
from oed.fourier import random_fourier
from oed.sequential.rivals import NoRunnerUpError, runner_up_file

CASE = StribeckCase()
QUICK = ["--starts", "1", "--max-iter", "15", "--samples", "60", "--constraint-points", "30", "--frequency", "1",
         "--quiet"]
#: ``--consistent``: the answer is the adopted model's consistent refit and the plain law's completion is not judged,
#: so the report's model file is the model the runner-up is the rival of. On its defaults the completion (Coulomb
#: friction and offsets the truth does not hold) validates 1.000 against 1.0034 here, taken since h-tie20 (the lower
#: score decides): the model file then holds the completed laws while the runner-up's BIC gap and the
#: discrimination's rival stay against the adopted model (``benchmarks/README.md``, h-tie20)
DIAGNOSE = ["diagnose", "--robot", "puma560", "--joints", "3", "--consistent"]


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """Training and validation records (two trajectories) and the report of `oed diagnose` on them."""
    folder = tmp_path_factory.mktemp("runner_up")
    CASE.record(CASE.first_trajectory(), seed=1).write(folder / "train.csv")
    CASE.record(random_fourier(CASE.robot, seed=4), seed=2).write(folder / "val.csv")
    code = main([*DIAGNOSE, "--data", str(folder / "train.csv"), "--validate", str(folder / "val.csv"),
                 "--out", str(folder / "report.json")])
    assert code == 0
    return folder


@pytest.fixture(scope="module")
def report(folder):
    return json.loads((folder / "report.json").read_text())


def test_report_keeps_the_other_friction_law_as_runner_up(report):
    assert [effect["spec"] for effect in report["effects"]] == ["stribeck:velocity"]
    runner_up = report["runner_up"]
    assert report["runner_up_reason"] is None
    assert runner_up["spec"] == "viscous,coulomb@2"
    assert runner_up["instead"] == "coulomb on tau2 in place of stribeck:velocity on tau2"
    assert [effect["spec"] for effect in runner_up["effects"]] == ["coulomb"]
    assert runner_up["effects"][0]["channels"] == ["tau2"] and runner_up["effects"][0]["parameters"] == ["fc2"]
    assert runner_up["round"] == 1
    assert runner_up["selection_bic_gap"] > 0 and runner_up["bic_gap"] > 0  # the data prefer the chosen law
    assert runner_up["n_parameters"] == len(report["model_file"]["theta"]) - 1  # fs2 fewer, no shape (vs2)
    assert runner_up["validation"]["mse"]["tau2"] > report["validation"]["after"]["mse"]["tau2"]
    assert runner_up["model_file"]["effects"] == runner_up["spec"]


def test_runner_up_bic_gap_is_the_chi_square_form_of_its_fit(folder, report):
    # the adopted model as fitted (the report's default may be its consistent refit: model_selection)
    chosen = IdentifiedModel(ModelFile.from_dict(report["model_file"]), estimate="unconstrained")
    rival = IdentifiedModel(ModelFile.from_dict(report["runner_up"]["model_file"]))
    record = chosen.prepare(chosen.read([folder / "train.csv"]))
    variance = np.asarray(chosen.file.channel_variance)
    rss = [np.sum((model.predict(record.q, record.dq, record.ddq) - record.channels(model.channels)) ** 2, axis=0)
           for model in (rival, chosen)]
    p = [len(model.theta) + len(model.file.shape) for model in (rival, chosen)]
    expected = bic_gap(rss[0], rss[1], variance, rss[0].size * record.q.shape[0], p[0], p[1])
    assert report["runner_up"]["bic_gap"] == pytest.approx(expected, rel=1e-3)


def test_oed_predict_reproduces_the_runner_up_validation_error(folder, report):
    rival = IdentifiedModel(runner_up_file(folder / "report.json"))
    mse = rival.evaluate([folder / "val.csv"]).prediction.mse
    for channel, value in report["runner_up"]["validation"]["mse"].items():
        assert mse[channel] == pytest.approx(value, rel=1e-6)


def test_streamed_diagnosis_keeps_the_same_runner_up(folder, report):
    out = folder / "streamed.json"
    code = main([*DIAGNOSE, "--data", str(folder / "train.csv"), "--validate", str(folder / "val.csv"),
                 "--out", str(out), "--chunk-size", "500"])
    assert code == 0
    streamed = json.loads(out.read_text())["runner_up"]
    assert streamed["spec"] == report["runner_up"]["spec"] and streamed["instead"] == report["runner_up"]["instead"]
    assert streamed["bic_gap"] == pytest.approx(report["runner_up"]["bic_gap"], rel=0.05)
    assert streamed["model_file"]["effects"] == "viscous,coulomb@2"
    out.unlink()


def test_design_discriminates_against_the_report_runner_up(folder, report):
    out = folder / "discriminate.json"
    code = main(["design", "--from", str(folder / "report.json"), "--discriminate", "--data", str(folder / "train.csv"),
                 "--out", str(out), *QUICK])
    assert code == 0
    document = json.loads(out.read_text())
    discrimination = document["discrimination"]
    assert document["criterion"] == "t-optimal"
    assert discrimination["from"] == "viscous,stribeck:velocity@2"
    assert discrimination["rival"] == report["runner_up"]["spec"]
    assert discrimination["rival_source"] == {"file": str(folder / "report.json"), "key": "runner_up.model_file"}
    assert all(value > 0 for value in discrimination["separation"].values())
    out.unlink()


def test_rival_file_wins_over_the_runner_up(folder):
    rival, out = folder / "tanh.json", folder / "discriminate.json"
    record = CASE.record(CASE.first_trajectory(), seed=1)
    rival.write_text(json.dumps({"model_file": CASE.model_document([record], "viscous,coulomb:tanh@2")}))
    code = main(["design", "--from", str(folder / "report.json"), "--discriminate", "--rival", str(rival),
                 "--data", str(folder / "train.csv"), "--out", str(out), *QUICK])
    assert code == 0
    discrimination = json.loads(out.read_text())["discrimination"]
    assert discrimination["rival"] == "viscous,coulomb:tanh@2"
    assert discrimination["rival_source"]["key"] == "model_file"
    out.unlink()
    rival.unlink()


def _refused(folder, capsys, arguments, message):
    out = folder / "bad.json"
    before = sorted(path.name for path in folder.iterdir())
    code = main(["design", "--out", str(out), *arguments, *QUICK])
    error = capsys.readouterr().err
    assert code == 2, error
    assert message in error, error
    assert sorted(path.name for path in folder.iterdir()) == before


def _two_joint_model() -> dict:
    robot = load_robot("puma560", joints=2)
    model = build_model(robot, "internal", "viscous")
    data = simulate(model, true_parameters(model, seed=0), random_fourier(robot, seed=3), rate_hz=200.0, periods=1,
                    noise={channel: 1.0 for channel in model.channels}, seed=1)
    return model_file_document(identify(model, data, covariance="classical"),
                               robot=RobotSource("puma560[2]", "puma560", 2),
                               preprocessing=Preprocessing("measured").to_dict())


def test_bad_discriminating_input_is_named_and_nothing_is_written(folder, report, capsys):
    data = str(folder / "train.csv")
    crafted = folder / "crafted.json"
    crafted.write_text(json.dumps({**report, "runner_up": None, "runner_up_reason": NOTHING_TRIED}))
    _refused(folder, capsys, ["--from", str(crafted), "--discriminate", "--data", data],
             "holds no runner-up: the diagnosis kept none (no move was fitted")
    crafted.write_text(json.dumps({"model_file": report["model_file"]}))  # a result.json of oed identify
    _refused(folder, capsys, ["--from", str(crafted), "--discriminate", "--data", data], "holds no runner-up (the key")
    same = {**report, "runner_up": {**report["runner_up"], "model_file": report["model_file"]}}
    crafted.write_text(json.dumps(same))
    _refused(folder, capsys, ["--from", str(crafted), "--discriminate", "--data", data], "the same model as --from")
    other = {**report, "runner_up": {**report["runner_up"], "model_file": _two_joint_model()}}
    crafted.write_text(json.dumps(other))
    _refused(folder, capsys, ["--from", str(crafted), "--discriminate", "--data", data], "another robot")
    crafted.unlink()
    rival = folder / "rival2.json"
    rival.write_text(json.dumps({"model_file": _two_joint_model()}))
    _refused(folder, capsys, ["--from", str(folder / "report.json"), "--discriminate", "--rival", str(rival),
                              "--data", data], "another robot")
    rival.unlink()
    _refused(folder, capsys, ["--from", str(folder / "report.json"), "--rival", str(folder / "report.json"),
                              "--data", data], "give --discriminate too")
    _refused(folder, capsys, ["--from", str(folder / "report.json"), "--discriminate", "--focus", "vs2", "--data", data],
             "not with --discriminate")
    _refused(folder, capsys, ["--from", str(folder / "report.json"), "--focus", "sigmoid", "--data", data],
             "'sigmoid' is neither a parameter of the model nor one of its effects")
    bounds = folder / "bounds.json"
    bounds.write_text(json.dumps({"q_max": [1, 1, 1], "dq_max": [1, 1, 1], "ddq_max": [1, 1, 1],
                                  "joint_names": ["a", "b", "c"]}))
    _refused(folder, capsys, ["--from", str(folder / "report.json"), "--discriminate", "--data", data,
                              "--bounds", str(bounds)], "the bounds name joints a, b, c")
    bounds.unlink()


def test_no_runner_up_when_no_move_was_fitted():
    record = CASE.record(CASE.first_trajectory(), seed=1)
    validation = CASE.record(random_fourier(CASE.robot, seed=4), seed=2)
    result = diagnose(build_model(CASE.robot, "internal", "viscous"), record, validation, candidates=(), delay=None)
    assert result.runner_up is None and result.runner_up_reason == NOTHING_TRIED
    assert result.to_dict()["runner_up"] is None and result.to_dict()["runner_up_reason"] == NOTHING_TRIED


def test_rival_of_the_last_move_swaps_the_chosen_effects_for_the_alternative():
    shape = np.array([0.1])
    chosen = Alternative(adds=(5,), removes=(2,), shapes={5: shape, 2: shape}, bic=-40.0)  # 5 replaced law 2
    move = LastMove(round=3, chosen=chosen, alternatives=())
    final = (1, 5, 7)  # 7 adopted after the move
    assert move.rival(final, Alternative((), (), {}, 0.0)) == (1, 7, 2)  # no move: the law replaced stays
    assert move.rival(final, Alternative((6,), (2,), {}, -35.0)) == (1, 7, 6)  # another law in its place
    assert move.rival(final, Alternative((9,), (), {}, -10.0)) == (1, 7, 2, 9)  # another effect, the law kept
    assert move.gap(Alternative((6,), (2,), {}, -35.0)) == pytest.approx(5.0)
    nothing = LastMove(round=1, chosen=None, alternatives=())
    assert nothing.rival((), Alternative((4,), (), {}, -3.0)) == (4,)
    assert nothing.gap(Alternative((4,), (), {}, -3.0)) == pytest.approx(-3.0)


def test_bic_gap_adds_the_parameter_penalty():
    variance = np.array([2.0, 4.0])
    gap = bic_gap(np.array([10.0, 20.0]), np.array([8.0, 12.0]), variance, 100, 5, 7)
    assert gap == pytest.approx(2.0 / 2.0 + 8.0 / 4.0 - 2 * np.log(100))


def test_no_runner_up_error_is_a_sequential_design_error(tmp_path):
    path = tmp_path / "r.json"
    record = CASE.record(CASE.first_trajectory(), seed=1)
    path.write_text(json.dumps({"model_file": CASE.model_document([record])}))
    with pytest.raises(NoRunnerUpError, match="--rival FILE"):
        runner_up_file(path)


def two_rivals():
    """Records, the declared model, two candidate blocks (Coulomb and offset on joint 2), a search outcome whose
    last round ranked them in that order, and the declared model's fit."""
    record = CASE.record(CASE.first_trajectory(), seed=1)
    validation = CASE.record(random_fourier(CASE.robot, seed=4), seed=2)
    declared = build_model(CASE.robot, "internal", "viscous")
    blocks = {index: Block(declared.kind, declared.robot, effect, declared.n_channels)
              for index, effect in enumerate((CoulombFriction(joints=(1,)), JointOffset(joints=(1,))))}
    last = LastMove(1, None, (Alternative((0,), (), {}, -50.0), Alternative((1,), (), {}, -5.0)))
    outcome = RunnerUpOutcome((), {}, False, np.ones(3), None, "", last_move=last)
    return record, validation, declared, blocks, outcome, identify(declared, record, validation)


def test_a_rival_that_cannot_be_fitted_is_passed_over_for_the_next():
    record, validation, declared, blocks, outcome, chosen = two_rivals()
    fitter, tried = in_memory_fitter(record, validation, chosen.delay), []

    def failing_first(model, indices, starts):
        tried.append(indices)
        if len(tried) == 1:
            raise ShapeSearchError("not determined")
        return fitter(model, indices, starts)

    runner_up, reason = fit_runner_up(declared, outcome, blocks, declared, chosen.estimate, failing_first)
    assert tried == [(0,), (1,)] and reason is None
    assert runner_up.spec == "viscous,offset@2" and runner_up.instead == "with offset on tau2"
    assert runner_up.selection_bic_gap == pytest.approx(-5.0)
    always = fit_runner_up(declared, outcome, blocks, declared, chosen.estimate,
                           lambda *_: (_ for _ in ()).throw(ShapeSearchError("not determined")))
    assert always[0] is None and always[1].startswith("no rival could be fitted (viscous,coulomb@2: not determined")


def test_a_rival_fitted_ahead_serves_its_own_model_only():
    record, validation, declared, blocks, outcome, chosen = two_rivals()
    fitter, asked = in_memory_fitter(record, validation, None), []

    def counted(model, indices, starts):
        asked.append(indices)
        return fitter(model, indices, starts)

    ahead = RivalAhead.planned(declared, outcome, blocks, declared)
    assert ahead.indices == (0,) and ahead.fit is None  # the best-ranked rival that is not the adopted model
    ahead = ahead.fitted(fitter)
    served = fit_runner_up(declared, outcome, blocks, declared, chosen.estimate, ahead.serving(counted))
    fresh = fit_runner_up(declared, outcome, blocks, declared, chosen.estimate, fitter)
    assert asked == [] and served[0].spec == fresh[0].spec == "viscous,coulomb@2"
    assert served[0].bic_gap == fresh[0].bic_gap and served[0].train_mse == fresh[0].train_mse
    # the joint refit chose the rival fitted ahead (a law simplified): the next rival is fitted in turn
    coulomb = build_model(CASE.robot, "internal", ("viscous", CoulombFriction(joints=(1,))))
    other = fit_runner_up(declared, outcome, blocks, coulomb, chosen.estimate, ahead.serving(counted))
    assert asked == [(1,)] and other[0].spec == "viscous,offset@2"
    # a fit that failed ahead is fitted again in turn, where its failure is told
    failed = RivalAhead.planned(declared, outcome, blocks, declared).fitted(
        lambda *_: (_ for _ in ()).throw(ShapeSearchError("not determined")))
    assert failed.fit is None
    fit_runner_up(declared, outcome, blocks, declared, chosen.estimate, failed.serving(counted))
    assert asked == [(1,), (0,)]
