"""`oed diagnose` keeps torque gains only when its answer with them predicts the validation record better than the
adopted model fitted to the torques as recorded, by `oed identify`'s rule
(:func:`estimation.consistent.torque_gains.diagnosed_gains_answer`)."""

from types import SimpleNamespace

import numpy as np

from estimation.consistent.model_selection import Candidate, ModelSelection
from estimation.consistent.torque_gains import TORQUE_GAINS_TOLERANCE, TorqueGains, diagnosed_gains_answer

GAINS = TorqueGains(channels=("tau1", "tau2"), values=np.array([1.1, 1.0]), std=np.array([0.01, 0.01]))


def answer(mse: dict[str, float], selection: str = "validation") -> ModelSelection:
    fit = SimpleNamespace(validation=SimpleNamespace(mse=mse, channels=tuple(mse)), train=None)
    return ModelSelection(chosen="consistent", selection=selection, reason="",
                          candidates=(Candidate("consistent", fit),), base="wls")  # type: ignore[arg-type]


def test_gains_kept_only_when_the_answer_with_them_validates_better_beyond_the_tolerance():
    # the payload plant's figures (h-gains2): with the gains 0.1303 / 17.75 / 0.00981, without 0.1344 / 17.82 /
    # 0.00981: 1 against 1.012
    without = answer({"tau1": 0.1344, "tau2": 17.82, "tau3": 0.00981})
    with_gains = answer({"tau1": 0.1303, "tau2": 17.75, "tau3": 0.00981})
    taken, why = diagnosed_gains_answer(without, with_gains, GAINS)
    assert taken and "kept" in why and "1.012" in why
    # within the tolerance (a tie keeps the model without them): refused, both scores said
    slight = answer({"tau1": 0.1344 / (1 + TORQUE_GAINS_TOLERANCE), "tau2": 17.82, "tau3": 0.00981})
    taken, why = diagnosed_gains_answer(without, slight, GAINS)
    assert not taken and "not taken" in why
    taken, why = diagnosed_gains_answer(without, answer({"tau1": 0.14, "tau2": 18.0, "tau3": 0.00981}), GAINS)
    assert not taken and "not taken" in why


def test_gains_kept_unsaid_when_nothing_measured_the_extrapolation():
    taken, why = diagnosed_gains_answer(answer({"tau1": 1.0}, "repeated-motion"), answer({"tau1": 2.0}), GAINS)
    assert taken and why == ""
