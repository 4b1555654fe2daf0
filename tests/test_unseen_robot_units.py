"""Robot descriptions as they come, twentieth round (issue 34; h-units20), the gaps h-unseen19 left:

- a description in grams read at the recorded torques' scale by the streamed ``oed identify`` as in memory (the
  consistent candidate's prior the description's bodies times the gains' geometric mean), and ``oed export`` of such
  an answer writing it (exit 0: the URDF in SI, as URDF specifies, said) where it exited 2 naming the scale;
- one function for the scale sentence of ``oed identify`` and ``oed diagnose``.

Cheap default cases check each piece; the slow case runs the verbs on a PUMA 3 described in grams."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from tests.test_unseen_robot_descriptions import in_grams, puma_text


def test_identify_and_diagnose_say_the_scale_by_one_function():
    """``oed identify`` (memory and streamed) and ``oed diagnose`` build their sentence of a description and torques
    in other units by one function (:func:`estimation.consistent.torque_gains.scale_notes`); at f91f2fe the
    diagnosis built it inline beside identify's own ``scale_notes``."""
    import oed.workflows.diagnose as diagnose
    import oed.workflows.identify as identify
    from estimation.consistent.torque_gains import TorqueGains, scale_note, scale_notes

    assert diagnose.scale_notes is scale_notes and identify.scale_notes is scale_notes
    grams = TorqueGains(("tau1", "tau2"), np.array([0.00105, 0.00106]), np.full(2, 1e-6))
    assert scale_notes(grams) == (scale_note(grams),) and "grams" in scale_notes(grams)[0]
    assert scale_notes(TorqueGains(("tau1", "tau2"), np.array([0.95, 1.05]), np.full(2, 1e-3))) == ()
    assert scale_notes(None) == ()


def test_the_streamed_identify_takes_the_prior_at_the_torques_scale(monkeypatch):
    """:func:`oed.workflows.identify.streamed_torque_gains_selection`: when the fitted gains say the torques are
    0.001 times the description's (grams) and no ``--prior`` is given, the answer's candidates are chosen again from
    the same sums with the description's bodies times that scale as the consistent candidate's prior, scored as the
    first choice was, as memory's ``torque_gains_selection`` does; at f91f2fe the streamed path only said it (its
    prior the description's, 1000 times too heavy). The gains' check and the choice are stubbed: this is the rule."""
    import dataclasses

    import oed.workflows.identify as identify
    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from estimation.consistent.torque_gains import TorqueGains

    model = build_model(load_robot("puma560", joints=3), "internal", "viscous,coulomb,offset")
    gains = TorqueGains(model.channels, np.array([0.00104, 0.00105, 0.00106]), np.full(3, 1e-6))
    monkeypatch.setattr(identify, "streamed_gains_check", lambda *args, **kwargs: (gains, False, "not taken"))
    chosen = []

    def summed_selection(sums, **settings):
        chosen.append(settings)
        return first

    monkeypatch.setattr(identify, "summed_selection", summed_selection)
    first = SimpleNamespace(unconstrained=SimpleNamespace(model=model), selection="validation", reason="chosen")
    @dataclasses.dataclass(frozen=True)
    class Args:  # the options the rule reads (IdentifyOptions checks its files)
        method: str = "auto"
        consistent: bool = False
        validate: tuple[str, ...] = ("validate.csv",)
        prior: str | None = None
        prior_weight: float | None = None
        link_bounds: str | None = None
        prior_scale: float | None = None

    args = Args()
    sums = SimpleNamespace(validation=SimpleNamespace(n_samples=100), train=None)
    scores = object()
    options = {"cutoff_hz": None, "decimation": None, "held_torques": None, "frequency_hz": None, "harmonics": None}
    selection, said = identify.streamed_torque_gains_selection(
        args, first, base="wls", methods=("wls", "ols"), chunk_size=500, options=options, ratio=None, still=False,
        sums=sums, scores=scores)
    assert said is not None and said[0] is gains and said[1] is False
    assert len(chosen) == 1, chosen
    settings = chosen[0]["consistent"]
    scale = float(np.exp(np.mean(np.log(gains.values))))
    assert np.allclose(settings.prior, scale * model.robot.standard_parameters, rtol=1e-12)
    assert "torques' scale" in settings.prior_source
    assert chosen[0]["score"] is scores and chosen[0]["base"] == "wls"
    chosen.clear()  # a prior the user gave is kept
    identify.streamed_torque_gains_selection(
        dataclasses.replace(args, prior="prior.json"), first, base="wls", methods=("wls", "ols"),
        chunk_size=500, options=options, ratio=None, still=False, sums=sums, scores=scores)
    assert chosen == []


def test_the_prior_at_the_torques_scale_is_one_setting_for_both_verbs():
    """:func:`oed.workflows.consistent.consistent_settings` with ``prior_scale`` (set by ``oed identify`` and, from
    this round, ``oed diagnose`` when the gains say the torques' scale): the description's bodies times it, its
    source a sentence :func:`~oed.workflows.consistent.prior_source_scale` reads back (``oed export`` judges the
    bodies at that scale); a ``--prior`` the user gave wins, and without the scale the description's bodies."""
    from dynamics.robots import load_robot
    from oed.workflows.consistent import consistent_settings, prior_source_scale, scaled_prior_source

    robot = load_robot("puma560", joints=3)
    args = SimpleNamespace(prior_weight=None, prior=None, link_bounds=None, prior_scale=0.00105493)
    settings = consistent_settings(args, robot)
    assert np.allclose(settings.prior, 0.00105493 * robot.standard_parameters, rtol=1e-12)
    assert prior_source_scale(settings.prior_source) == pytest.approx(0.00105493, rel=1e-6)
    assert prior_source_scale(scaled_prior_source(2.5e-5)) == pytest.approx(2.5e-5, rel=1e-6)
    assert consistent_settings(SimpleNamespace(**{**vars(args), "prior_scale": None}), robot).prior is None
    for other in ("robot description", "prior.json", None, "robot description times x (the recorded torques' scale)"):
        assert prior_source_scale(other) is None


def test_export_judges_the_bodies_at_the_torques_scale(tmp_path):
    """``oed export`` of an answer whose prior was the description's bodies at the torques' scale (a description in
    grams): its bodies, in kg, are judged against the description's at that scale
    (:func:`oed.workflows.export.torques_scale` from the result's gains, by the rule that took it), and the line it
    prints says the URDF is SI and names the links it did not identify. At f91f2fe every body was refused as a
    thousandth of the description's (exit 2)."""
    from dynamics.urdf import robot_from_urdf
    from estimation.identification.export import implausible_links
    from oed.workflows.export import scale_line, torques_scale

    path = tmp_path / "grams.urdf"
    path.write_text(in_grams(puma_text().replace(  # a base with a body, as a CAD export gives one
        '<link name="base_link" />', '<link name="base_link"><inertial><origin xyz="0 0 0.1" rpy="0 0 0" /><mass '
        'value="20" /><inertia ixx="0.5" ixy="0" ixz="0" iyy="0.5" iyz="0" izz="0.3" /></inertial></link>')))
    robot = robot_from_urdf(path)
    links = (0.00105 * robot.standard_parameters).reshape(-1, 10)  # the bodies in kg
    model = SimpleNamespace(robot=robot, estimate="consistent", file=SimpleNamespace(consistent_links=links))
    def against(scale=None):  # the bodies far from the description's (the PUMA's massless link 1 is degenerate)
        return [finding for finding in implausible_links(model, scale=scale) if "in the description" in finding]

    assert len(against()) >= 4  # against the description in grams
    result = tmp_path / "result.json"
    gains = {"channels": {f"tau{j}": {"value": value, "std": 1e-6, "determined": True}
                          for j, value in enumerate((0.00104, 0.00105, 0.00106), start=1)}, "scale": ""}
    result.write_text(json.dumps({"consistent": {"prior": "robot description times 0.00105 (the recorded torques' "
                                                          "scale)"}, "torque_gains": gains}))
    scale = torques_scale(result)
    assert scale == pytest.approx(0.00105, rel=1e-3)
    assert against(scale) == []
    # the verbs' link checks alike (result.json's plausibility.consistent_links and the warnings)
    from oed.workflows.model_files import consistent_link_findings

    estimate = SimpleNamespace(link_parameters=lambda: links)
    scaled = SimpleNamespace(prior_source="robot description times 0.00105 (the recorded torques' scale)",
                             estimate=estimate)
    assert not [text for text in consistent_link_findings(robot, scaled) if "in the description" in text]
    plain = SimpleNamespace(prior_source="robot description", estimate=estimate)
    assert len([text for text in consistent_link_findings(robot, plain) if "in the description" in text]) >= 4
    said = scale_line(path.read_text(), robot, scale)
    assert "SI" in said and "grams" in said and "base_link" in said, said
    result.write_text(json.dumps({"consistent": {"prior": "robot description"}, "torque_gains": gains}))
    assert torques_scale(result) is None  # the prior the description's: judged against it as before
    assert torques_scale(tmp_path / "absent.json") is None


@pytest.mark.slow
def test_a_description_in_grams_identified_streamed_as_in_memory_and_exported(tmp_path):
    """The PUMA's first three joints described in grams (8 s / 3 s / 5 s at 250 Hz, 2 % noise): the streamed
    ``oed identify`` (``--chunk-size 500``) takes the prior at the torques' scale as memory does, and the consistent
    alternatives of both predict the test record alike (relative 1e-9; measured 2e-10); ``oed export`` of the answer
    exits 0 writing the identified bodies in SI and saying so, and the written URDF reads back those bodies; the
    default ``oed diagnose`` takes the same prior and its answer exports alike."""
    import oed
    from dynamics.urdf import robot_from_urdf
    from tests.test_unseen_robot_kinds import quiet
    from tests.test_torque_gains import _puma3_files

    urdf, _ = _puma3_files(tmp_path, np.ones(3))
    urdf.write_text(in_grams(urdf.read_text()))
    documents, errors = {}, {}
    for name, options in (("memory", {}), ("streamed", {"chunk_size": 500})):
        oed.identify(urdf=urdf, data=tmp_path / "train.csv", validate=tmp_path / "validate.csv",
                     friction="viscous,coulomb,offset", **options).write(tmp_path / f"{name}.json")
        documents[name] = json.loads((tmp_path / f"{name}.json").read_text())
        assert "torques' scale" in documents[name]["consistent"]["prior"], documents[name]["consistent"]["prior"]
        assert not [text for text in documents[name]["plausibility"]["consistent_links"] if "in the description" in
                    text], documents[name]["plausibility"]
        errors[name] = oed.predict(model=tmp_path / f"{name}.json", data=tmp_path / "test.csv",
                                   alternative="consistent").evaluation.prediction.mse
    assert documents["streamed"]["identification_path"] == "streamed"
    for channel, value in errors["memory"].items():
        assert errors["streamed"][channel] == pytest.approx(value, rel=1e-9), (channel, errors)
    code, message = quiet(["export", "--model", str(tmp_path / "memory.json"), "--urdf", str(tmp_path / "out.urdf")])
    assert code == 0 and "Traceback" not in message, message
    assert "times the robot's" in message, message  # the line's end (quiet keeps stdout's tail)
    written = robot_from_urdf(tmp_path / "out.urdf")
    links = np.array(documents["memory"]["model_file"]["consistent"]["links"], dtype=float)
    assert np.allclose(written.standard_parameters, links.reshape(-1), rtol=1e-9, atol=1e-12)
    # oed diagnose takes the same prior (at f91f2fe the description's: joint 2's body 1041 kg, export exit 2)
    code, message = quiet(["diagnose", "--urdf", str(urdf), "--data", str(tmp_path / "train.csv"), "--validate",
                           str(tmp_path / "validate.csv"), "--out", str(tmp_path / "diagnose.json")])
    assert code == 0, message
    diagnosed = json.loads((tmp_path / "diagnose.json").read_text())
    assert "torques' scale" in diagnosed["consistent"]["prior"], diagnosed["consistent"]["prior"]
    code, message = quiet(["export", "--model", str(tmp_path / "diagnose.json"), "--urdf", str(tmp_path / "d.urdf")])
    assert code == 0 and "times the robot's" in message, message


def scaled_arm(text: str, length: float, mass: float) -> str:
    """``text`` with every ``<origin xyz>`` times ``length``, every mass times ``mass`` and every inertia times
    ``mass length²`` (a similar arm of another size)."""
    import re

    def xyz(found: re.Match) -> str:
        return 'xyz="' + " ".join(f"{float(value) * length:.10g}" for value in found.group(1).split()) + '"'

    text = re.sub(r'xyz="([^"]+)"(?=\s*rpy)', xyz, text)
    text = re.sub(r'<mass value="([^"]+)"', lambda found: f'<mass value="{float(found.group(1)) * mass:.10g}"', text)
    return re.sub(r'\b(i[xyz]{2})="([^"]+)"',
                  lambda found: f'{found.group(1)}="{float(found.group(2)) * mass * length ** 2:.10g}"', text)


def test_a_tiny_arm_or_light_links_in_inches_are_said(tmp_path):
    """Descriptions in inches the reader's refusal does not judge: the desk arm at a fifth of its size (2.1 cm,
    1.1 g moving: a 0.83 m chain in inches) and with every link under 10 g (8.1 g moving: 4.1 m in inches) weigh
    0.0019 and 0.00011 kg over their span cubed, where robots' descriptions weigh 0.8 to 50: read with a warning
    naming placeholders and inches (at f91f2fe: without a word). The same arms in metres (117 and 7.0) are not
    said; a simulator's placeholders (a gram a link on the PUMA: 0.006) are."""
    from tests.test_unseen_robot_desks import DESK_ARM, placeholder_masses
    from tests.test_unseen_robot_descriptions import in_inches, read

    for name, text in (("tiny", scaled_arm(DESK_ARM, 0.2, 0.008)), ("light", scaled_arm(DESK_ARM, 1.0, 0.06))):
        _, said = read(text, tmp_path, f"{name}_metres")
        assert not [message for message in said if "weigh" in message], said
        _, said = read(in_inches(text), tmp_path, f"{name}_inches")
        assert any("inches" in message and "0.0254" in message and "placeholder" in message for message in said), said
    _, said = read(placeholder_masses(puma_text()), tmp_path, "placeholders")
    assert any("placeholder" in message for message in said), said


def with_dynamics(text: str, damping, friction) -> str:
    """Each ``<limit>`` followed by ``<dynamics damping friction>`` of the joint's values (a ROS description's)."""
    import re

    values = iter(zip(damping, friction))

    def put(found: re.Match) -> str:
        viscous, coulomb = next(values)
        return f'{found.group(1)}\n    <dynamics damping="{viscous:.6g}" friction="{coulomb:.6g}" />'

    return re.sub(r"(<limit [^>]*/>)", put, text)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="measured (h-units20): the URDF's <dynamics> as the consistent fit's friction "
                   "prior, its values a fifth of the truth's, makes the default oed diagnose predict the test record "
                   "1.47x worse (joint 2 2.0x), where the true values gain nothing (0.0272 with and without): not read "
                   "as a prior")
def test_a_urdfs_dynamics_as_the_friction_prior_never_costs(tmp_path, monkeypatch):
    """Should a URDF's ``<dynamics damping friction>`` be the consistent fit's prior for each joint's viscous and
    Coulomb friction (:mod:`estimation.consistent.effect_prior`, as an MJCF's ``damping`` and ``frictionloss`` are,
    weighted with the bodies by the held-out prior weight)? Measured with the reader patched to read them: the PUMA 3
    (3 s / 2 s / 8 s at 250 Hz, no dq, a point-to-point test) with the truth's values gains nothing (identify and
    diagnose 0.0272 of the plain fit, as without), and with values a fifth of the truth's the default ``oed
    diagnose`` predicts the test 0.0399 (joint 2 0.086 against 0.043): a description's friction is often a
    simulator's guess, so it stays unread (the export writes the identified friction into it). The PUMA 6 (10 s /
    4 s / 8 s), true, 5x, a fifth and the KUKA-like guess (1.0 / 10.0): 0.0950 to 0.0958 against 0.0958."""
    import dataclasses

    import dynamics.urdf as urdf
    from dynamics.models import build_model
    from tests.test_unseen_robot_days import Day, logs, run_day
    from tests.test_unseen_robot_labs import Lab, puma, true_theta

    original = urdf._joint

    def reading(path, model, joint_id):  # the reader as it would read them
        joint, index = original(path, model, joint_id), model.joints[joint_id].idx_v
        return dataclasses.replace(joint, damping=max(float(model.damping[index]), 0.0),
                                   friction=max(float(model.friction[index]), 0.0))

    monkeypatch.setattr(urdf, "_joint", reading)
    lab = Lab("PUMA 3, <dynamics> a fifth of the truth's", puma(3), *logs((3.0, 2.0, 8.0)),
              test_motion="point-to-point")
    theta = true_theta(lab, tmp_path)
    names = list(build_model(lab.robot(), "internal", "viscous,coulomb,offset").parameter_names)
    fv, fc = ([0.2 * theta[names.index(f"{law}{j}")] for j in (1, 2, 3)] for law in ("fv", "fc"))
    totals = {}
    for label, described in (("without", None), ("a fifth", lambda text: with_dynamics(text, fv, fc))):
        folder = tmp_path / label.replace(" ", "_")
        folder.mkdir()
        mse = run_day(Day(lab, described=described), folder)["mse"]
        totals[label] = {verb: (sum(mse[verb]) / sum(mse[f"plain OLS ({verb}'s samples)"]),
                                np.array(mse[verb]) / np.array(mse[f"plain OLS ({verb}'s samples)"]))
                         for verb in ("default", "diagnose")}
    print(totals)
    for verb in ("default", "diagnose"):
        total, joints = totals["a fifth"][verb]
        assert total <= 1.02 * totals["without"][verb][0], (verb, totals)
        assert np.all(joints <= 1.05 * totals["without"][verb][1]), (verb, totals)
