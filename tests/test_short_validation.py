"""A validation record confirms only what it can tell apart (issue 34: "no false effects"; the sweep's
``tx40-shortval``: a Stäubli TX40 with a 1 s validation record took ``coulomb:tanh[q2-q3]``, whose combined velocity
had the sign of ``q̇_2`` and of ``−q̇_3`` at every sample of the training and validation records, and predicted joint 3
of a motion where they differ 5.4x worse than a plain fit). A Coulomb law on a joint combination is proposed only
when the training and the validation records both hold samples where its sign differs from one of its joints'."""

from __future__ import annotations

import dataclasses


from dynamics.effects.motor import pair_combinations
from estimation.diagnosis.candidates.coupling import MIN_APART, coupling_candidates, signs_apart
from tests.corpus.cases import ALONE
from tests.corpus.records import declared_model, records

COUPLED = next(case for case in ALONE if case.name == "coupled coulomb q2+q3")


def moving_together(record, joints=(1, 2), scale=0.5):
    """``record`` with the second of ``joints`` moving as the first, scaled: every sample of one sign on both."""
    dq = record.dq.copy()
    dq[:, joints[1]] = scale * dq[:, joints[0]]
    return dataclasses.replace(record, dq=dq)


def pair_names(candidates):
    return {candidate.name for candidate in candidates if "q2+q3" in candidate.name and "coulomb" in candidate.name}


def test_signs_apart_counts_the_samples_where_a_combination_and_a_joint_disagree():
    _, validate = records(COUPLED)
    pair = next(p for p in pair_combinations(3, "coulomb") if p.name == "coulomb[q2+q3]")
    assert signs_apart(pair, validate) >= MIN_APART
    assert signs_apart(pair, moving_together(validate)) == 0.0


def test_a_held_out_record_that_cannot_tell_a_pair_from_its_joints_laws_does_not_let_it_in():
    """The training record traces the pair (its truth holds it); a validation record where the two joints always
    move the same way cannot tell it from their own Coulomb laws, and the pair is not proposed; with a validation
    record of the truth's motion it is."""
    train, validate = records(COUPLED)
    model = declared_model()
    assert "coulomb[q2+q3]" in pair_names(coupling_candidates(model, train=train))
    assert "coulomb[q2+q3]" in pair_names(coupling_candidates(model, train=train, held_out=validate))
    assert pair_names(coupling_candidates(model, train=train, held_out=moving_together(validate))) == set()
    assert pair_names(coupling_candidates(model, train=moving_together(train), held_out=validate)) == set()


