"""The plain-law swap judged on the models the default answer chooses between (issue 34): a mixed model refused on
the unconstrained fits' validation score alone (estimation.diagnosis.plain_laws, ``keep_refused``) is adopted by
``oed diagnose`` when the better of it as fitted and its consistent refit predicts the validation record better than
the better of the diagnosed model's two, by the default answer's relative criterion (oed.workflows.diagnose.judged_swap)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from estimation.diagnosis.results import Diagnosis
from oed.workflows import diagnose as workflow

CHANNELS = ("tau1", "tau2", "tau3")


def _selection(mse: list[float], selection: str = "validation") -> SimpleNamespace:
    validation = SimpleNamespace(channels=CHANNELS, mse=dict(zip(CHANNELS, mse)))
    return SimpleNamespace(selection=selection, chosen="consistent",
                           chosen_candidate=SimpleNamespace(fit=object(), validation=validation))


@pytest.fixture
def judged(monkeypatch):
    """``judged_swap`` with the selections given per diagnosis (the refits are not what is tested here)."""
    def run(kept_mse, swap_mse, *, selection="validation", consistent=False):
        answers = {"kept": _selection(kept_mse, selection), "swap": _selection(swap_mse, selection)}
        calls = []

        def select(args, diagnosis, records, *, complete=True):
            assert diagnosis.swap is None  # each model's answer, not the pair
            calls.append(diagnosis.after)
            return answers[diagnosis.after]

        monkeypatch.setattr(workflow, "diagnosis_selection", select)
        # the plain law's completion of the model kept is tested in tests/test_diagnose_other_motion_plain_law.py
        monkeypatch.setattr(workflow, "completed_selection", lambda args, diagnosis, records, selection: selection)
        swap = Diagnosis(effects=(), rejected=(), before=None, after="swap", residuals=None)
        diagnosis = Diagnosis(effects=(), rejected=(), before=None, after="kept", residuals=None, runner_up="rival",
                              swap=swap)
        chosen, selected, note = workflow.judged_swap(SimpleNamespace(consistent=consistent), diagnosis, None)
        assert (note is None) == (calls == ["kept"])
        if note is not None:
            assert note.endswith("adopted" if chosen.after == "swap" else "refused")
        return chosen, selected, calls
    return run


def test_the_swap_is_adopted_when_its_answer_validates_better(judged):
    chosen, selected, calls = judged([1.0, 1.0, 2.0], [1.0, 0.9, 1.0])
    assert (chosen.after, chosen.swap, chosen.runner_up) == ("swap", None, "rival")
    assert selected.chosen_candidate.validation.mse["tau3"] == 1.0
    assert calls == ["kept", "swap"]  # one selection (one consistent refit) more, only for the refused swap


def test_the_diagnosed_model_is_kept_when_the_swap_trades_one_joint_for_another(judged):
    # relative criterion: the swap halves tau3 but triples tau2 -> mean (1 + 3 + 1)/3 > (1 + 1 + 2)/3
    chosen, _, _ = judged([1.0, 1.0, 2.0], [1.0, 3.0, 1.0])
    assert (chosen.after, chosen.swap) == ("kept", None)


def test_a_tie_keeps_the_diagnosed_model(judged):
    chosen, _, _ = judged([1.0, 1.0, 1.0], [1.0, 1.0, 1.0])
    assert chosen.after == "kept"


@pytest.mark.parametrize("selection, consistent", [("repeated-motion", False), ("no-validation", False),
                                                   ("given", True)])
def test_no_swap_without_a_comparison_on_another_motion(judged, selection, consistent):
    chosen, _, calls = judged([1.0, 1.0, 9.0], [1.0, 1.0, 1.0], selection=selection, consistent=consistent)
    assert chosen.after == "kept"
    assert calls == ["kept"]
