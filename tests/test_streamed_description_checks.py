"""The streamed ``oed identify`` and ``oed diagnose`` (``--chunk-size``) check the mount and the friction drift as the
in-memory verbs do (h-streamchecks): the same ``friction_drift`` figures and the same warnings, and both verbs try
a found gravity as a candidate of the answer on both paths (``oed identify``: h-streamsel; ``oed diagnose``: the
whole diagnosis run again with it, h-streamdiag), on simulated PUMA 560
records whose truth holds what the check is for (:mod:`tests.test_unseen_robot_mounts`): the friction 30 % lower
once warm (training cold, validation at 2 min), and the arm on a wall whose URDF gives no mount.

The streamed path reads the files in blocks and keeps, in one more pass, the samples the in-memory checks keep (their
evenly spaced rows of each prepared record, :mod:`estimation.streaming.description_checks`); the checks then run on
them. The drift's figures equal the in-memory ones within :data:`DRIFT_TOLERANCE` (the blocks' filter is the
in-memory one up to its edges). The streamed diagnosis checks the mount before its search on the search's subsamples
(the whole record when it holds fewer than 10 000 samples, as here), as in memory.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from tests.test_unseen_robot_kinds import quiet
from tests.test_unseen_robot_labs import puma
from tests.test_unseen_robot_mounts import Mounted, six, write_records

#: the largest difference allowed between the streamed and the in-memory friction scales and standard errors
#: (relative; measured: below 1e-9 on these records, whose filter the blocks reproduce)
DRIFT_TOLERANCE = 1e-6
#: the streamed reader's block (samples): each 3 s record is read in several blocks
CHUNK = "300"

WARMING = Mounted("PUMA 3 joints, friction 30 % lower once warm", puma(3), *six((8.0, 3.0, 5.0)), warming=0.3)
WALL = Mounted("PUMA 3 joints on a wall, the URDF without the mount", puma(3), *six((8.0, 3.0, 5.0)), mount="wall",
               described="floor")


def _run(verb: str, case: Mounted, folder, *options: str) -> dict:
    urdf, _, files, _ = write_records(case, folder)
    out = folder / f"{verb}{'-streamed' if options else ''}.json"
    more = ["--friction", "viscous,coulomb,offset"] if verb == "identify" else []
    code, message = quiet([verb, "--urdf", str(urdf), "--data", str(files["train"]), "--validate",
                           str(files["validate"]), *more, *options, "--out", str(out)])
    assert code == 0, message
    return json.loads(out.read_text())


def _said(document: dict) -> list[str]:
    warnings = document["warnings"]
    return warnings if isinstance(warnings, list) else [text for part in warnings.values() for text in part]


def _numbers_apart(first: str, second: str) -> float:
    """The largest relative difference between the numbers of two sentences that are otherwise the same."""
    pattern = r"-?\d+(?:\.\d+)?(?:e-?\d+)?"
    assert re.sub(pattern, "#", first) == re.sub(pattern, "#", second), (first, second)
    pairs = [(float(a), float(b)) for a, b in zip(re.findall(pattern, first), re.findall(pattern, second))]
    return max((abs(a - b) / max(abs(a), abs(b), 1e-12) for a, b in pairs), default=0.0)


def _same_drift(memory: dict, streamed: dict) -> None:
    assert streamed["not_computed"].get("friction_drift") is None
    drift, expected = streamed["friction_drift"], memory["friction_drift"]
    assert drift is not None and set(drift) == set(expected) and set(drift["joints"]) == set(expected["joints"])
    for name, joint in expected["joints"].items():
        for key, value in joint.items():
            if isinstance(value, bool):
                assert drift["joints"][name][key] is value, (name, key)
            else:
                assert drift["joints"][name][key] == pytest.approx(value, rel=DRIFT_TOLERANCE, abs=1e-12), (name, key)


#: how the mount's warning ends when the answer holds the found gravity: both verbs try it as a candidate of the
#: answer on both paths (:mod:`estimation.consistent.mounted_gravity`; taken on the wall, where it validates better)
TAKEN = ("; the answer is fitted with the found gravity (it predicts the validation record better: the model "
         "selection's reason gives the scores), which the result file holds for predict and export")
KEPT = "; this fit keeps the description's gravity"
#: a diagnosis that keeps the description's gravity leaves the explained joints' position laws out (an answer fitted
#: with the found gravity tried every law)
KEPT_TOO = "; the diagnosis keeps it too, and tries no spring or position ripple on "
#: the largest relative difference allowed between the streamed and the in-memory diagnosis's figures on these
#: records (the same samples; measured: 3e-11 for the validation and test errors, 1e-9 for the parameters)
SAME_ANSWER = 1e-6


def _checked(text: str) -> str:
    """A warning without the words saying whether the answer took the found gravity (the paths differ there only)."""
    return text.replace(TAKEN, "").replace(KEPT, "").split(KEPT_TOO)[0]


def _same_words(memory: dict, streamed: dict, start: str) -> list[str]:
    said = [_checked(text) for text in _said(memory) if start in text]
    streamed_said = [_checked(text) for text in _said(streamed) if start in text]
    assert len(said) == len(streamed_said), (said, streamed_said)
    for first, second in zip(said, streamed_said):
        assert first == second or _numbers_apart(first, second) < 0.01, (first, second)
    return said


@pytest.mark.parametrize("case", [WARMING, WALL], ids=["warming", "wall"])
def test_the_streamed_identify_checks_the_drift_and_the_mount_as_in_memory(case, tmp_path):
    memory = _run("identify", case, tmp_path)
    streamed = _run("identify", case, tmp_path, "--chunk-size", CHUNK)
    assert streamed["identification_path"] == "streamed" and memory["identification_path"] == "in-memory"
    _same_drift(memory, streamed)
    drifted = _same_words(memory, streamed, "friction differs between the training and the validation record")
    mounts = _same_words(memory, streamed, "gravity load points elsewhere")
    assert bool(drifted) == bool(case.warming) and bool(mounts) == (case.mount != case.described), (drifted, mounts)
    assert "gravity" not in streamed["not_computed"]  # a mount found is a candidate streamed too (h-streamsel)
    if mounts:  # both take the found gravity (it validates better on the wall): the same answer, the same gravity
        assert any(TAKEN in text for text in _said(memory)), _said(memory)
        assert any(TAKEN in text for text in _said(streamed)), _said(streamed)
        assert "the gravity the mount check found" in streamed["model_selection"]["reason"]
        # the log less the description's gravity torque is tried streamed too, where the torques hold no gravity load
        # (h-streamload): not on the wall, whose torques hold a turned one
        assert "subtracted" not in streamed["not_computed"] and "subtracted" not in streamed["model_file"]
    assert streamed["chosen"] == memory["chosen"]
    np.testing.assert_allclose(streamed["model_file"]["gravity"], memory["model_file"]["gravity"], rtol=1e-6)
    values = {name: np.array([p["value"] for p in document["parameters"]])
              for name, document in (("memory", memory), ("streamed", streamed))}
    np.testing.assert_allclose(values["streamed"], values["memory"], rtol=1e-4,
                               atol=1e-4 * np.abs(values["memory"]).max())
    marked = [joint["marked"] for joint in streamed["friction_drift"]["joints"].values()]
    assert all(marked) if case.warming else not any(marked)


@pytest.mark.slow
@pytest.mark.parametrize("case", [WARMING, WALL], ids=["warming", "wall"])
def test_the_streamed_diagnose_checks_the_drift_and_the_mount_as_in_memory(case, tmp_path):
    memory = _run("diagnose", case, tmp_path)
    streamed = _run("diagnose", case, tmp_path, "--chunk-size", CHUNK)
    assert streamed["diagnosis_path"] == "streamed"
    _same_drift(memory, streamed)
    drifted = _same_words(memory, streamed, "friction differs between the training and the validation record")
    mounts = _same_words(memory, streamed, "gravity load points elsewhere")
    assert bool(drifted) == bool(case.warming) and bool(mounts) == (case.mount != case.described), (drifted, mounts)
    assert "gravity" not in streamed["not_computed"]  # a mount found is a candidate streamed too (h-streamdiag)
    if mounts:  # both run the diagnosis again with the found gravity and take its answer (it validates better)
        assert any(TAKEN in text for text in _said(memory)), _said(memory)
        assert any(TAKEN in text for text in _said(streamed)), _said(streamed)
        assert "the gravity the mount check found" in streamed["model_selection"]["reason"]
        assert not [effect for effect in streamed["effects"]
                    if effect["name"] == "spring" and "tau1" in effect["channels"]]
        assert "subtracted" not in streamed["not_computed"] and "subtracted" not in streamed["model_file"]
        assert streamed["model_selection"]["paired_difference"] is not None
    _same_answer(memory, streamed, tmp_path)


def _same_answer(memory: dict, streamed: dict, folder) -> None:
    """The streamed diagnosis gives memory's answer: the same effects, chosen model and gravity, its parameters,
    its validation errors, and ``oed predict``'s errors on the test record no choice saw (:data:`SAME_ANSWER`)."""
    assert [(effect["name"], effect["channels"]) for effect in streamed["effects"]] \
        == [(effect["name"], effect["channels"]) for effect in memory["effects"]]
    assert streamed["model_file"]["chosen"] == memory["model_file"]["chosen"]
    np.testing.assert_allclose(streamed["model_file"]["gravity"], memory["model_file"]["gravity"], rtol=SAME_ANSWER)
    theta = {name: np.asarray(document["model_file"]["theta"], dtype=float)
             for name, document in (("memory", memory), ("streamed", streamed))}
    np.testing.assert_allclose(theta["streamed"], theta["memory"], rtol=SAME_ANSWER,
                               atol=SAME_ANSWER * np.abs(theta["memory"]).max())
    for channel, value in memory["validation"]["chosen"]["mse"].items():
        assert streamed["validation"]["chosen"]["mse"][channel] == pytest.approx(value, rel=SAME_ANSWER), channel
    # whether the validation record tells the answer from the consistent refit: the streamed one from the validation
    # sums of each block (measured on the wall: 4e-10 apart)
    paired = [document["model_selection"]["paired_difference"] for document in (memory, streamed)]
    assert (paired[1] is None) == (paired[0] is None)
    if paired[0] is not None:
        assert paired[1]["best"] == paired[0]["best"] and paired[1]["within_noise"] == paired[0]["within_noise"]
        for key in ("difference", "standard_error"):
            assert paired[1][key] == pytest.approx(paired[0][key], rel=SAME_ANSWER), key
    test = folder / "test.csv"  # tests.test_unseen_robot_mounts.write_records
    assert test.exists(), test
    errors = {}
    for name, document in (("memory", memory), ("streamed", streamed)):
        model = folder / f"{name}-model.json"
        model.write_text(json.dumps(document))
        metrics = folder / f"{name}-test.json"
        code, message = quiet(["predict", "--model", str(model), "--data", str(test), "--metrics", str(metrics)])
        assert code == 0, message
        errors[name] = json.loads(metrics.read_text())["mse"]
    for channel, value in errors["memory"].items():
        assert errors["streamed"][channel] == pytest.approx(value, rel=SAME_ANSWER), channel


def test_the_streamed_checks_keep_the_in_memory_rows():
    """The rows the streamed pass keeps are those the in-memory checks keep (their rule: evenly spaced, rounded
    down), and a record thinned so is kept whole by the checks (the checks then see the same rows)."""
    from estimation.streaming.description_checks import evenly_spaced_rows

    for n in (5, 2999, 3000, 3001, 14_000, 123_457):
        for count in (1000, 3000, 6000):
            rows = evenly_spaced_rows(n, count)
            assert np.array_equal(rows, np.unique(np.linspace(0, n - 1, min(n, count)).astype(int)))
            assert rows.size == min(n, count)
            assert np.array_equal(evenly_spaced_rows(rows.size, count), np.arange(rows.size))
