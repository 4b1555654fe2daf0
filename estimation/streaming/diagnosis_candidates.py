"""The candidates of the streamed diagnosis (:mod:`estimation.streaming.diagnosis`): their column
blocks, their shapes and where their columns sit in the sums.

Shaped laws (``coulomb:tanh``, ``stribeck:velocity``, ``sigmoid``, ``ripple``) cannot be summed at an
unknown shape: :func:`shape_search` searches each one's shape parameters on the training subsample,
against the declared model (the in-memory diagnosis's first round,
:func:`estimation.diagnosis.candidates.trials.fit_or_reason`, at the channel weights of the subsample's
identification); the sums are then taken at those shapes (:class:`StreamedCandidates`).
"""

from __future__ import annotations

import pickle
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from dynamics.effects.linear import Effect
from dynamics.effects.shaped import FRICTION_LAWS
from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel
from dynamics.transmission import Transmission
from estimation.diagnosis.candidates.trials import candidate_label, fit_or_reason
from estimation.diagnosis.candidates.coupling import coupling_candidates
from estimation.diagnosis.forward_selection import candidate_blocks, declared_friction_joints
from estimation.diagnosis.results import RejectedEffect
from estimation.diagnosis.search import default_candidates
from estimation.estimators.effect_blocks import Block, States
from estimation.estimators.separable_least_squares import FixedPart, solve_linear
from estimation.identification.fit import identify
from estimation.streaming.diagnosis_sums import ColumnLayout

__all__ = ["StreamedCandidates", "shape_search", "streamed_candidates"]


def shape_search(model: IdentificationModel, blocks: dict[int, Block], subsample: Measurements,
                  weights: np.ndarray) -> tuple[dict[int, np.ndarray], dict[int, RejectedEffect]]:
    """Each shaped law's shape on the subsample against the declared model (the in-memory first
    round), and the laws whose search failed."""
    fixed = FixedPart.from_arrays(model.evaluate_base(subsample.q, subsample.dq, subsample.ddq),
                                  subsample.channels(model.channels))
    states = States(subsample.q, subsample.dq, subsample.ddq)
    rss = solve_linear(fixed, [], states, [], weights).rss
    declared = declared_friction_joints(model)
    shapes, failed = {}, {}
    for index, block in blocks.items():
        if block.n_shape == 0:
            shapes[index] = np.zeros(0)
            continue
        joints = {int(model.channels[row][3:]) - 1 for row in block.rows if model.channels[row].startswith("tau")}
        if block.effect.name in FRICTION_LAWS and joints & declared:
            shapes[index] = np.array([p.starts[0] for p in block.parameters], dtype=float)  # rejected in the loop
            continue
        outcome = fit_or_reason((index,), [block], fixed, states, weights, rss, None, search=False)
        if isinstance(outcome, str):
            failed[index] = RejectedEffect(block.effect.name, tuple(model.channels[r] for r in block.rows),
                                           outcome + " (on the subsample)", candidate_label(block.effect))
        else:
            shapes[index] = outcome.fit.shape
    return shapes, failed



@dataclass(frozen=True)
class StreamedCandidates:
    """The candidates with columns in the sums, their fixed shapes and where their columns are."""

    blocks: dict[int, Block]
    shapes: dict[int, np.ndarray]
    rejected: dict[int, RejectedEffect]
    n_candidates: int
    layout: ColumnLayout
    plan: bytes  # the pickled effects and shapes the workers evaluate

    @property
    def columns(self) -> dict[int, tuple[int, ...]]:
        return {index: self.layout.blocks[slot] for slot, index in enumerate(self.blocks)}

    def final_plan(self, chosen: list[int]) -> bytes:
        return pickle.dumps(([self.blocks[i].effect for i in chosen], [self.shapes[i] for i in chosen]))


def streamed_candidates(model: IdentificationModel, candidates: Sequence[Effect] | None, sample: Measurements,
                        lap: Callable[[str], None], transmission: Transmission | None = None) -> StreamedCandidates:
    """The candidates (default: :func:`~estimation.diagnosis.search.default_candidates`, the pairs
    traced on the subsample and the coupled motors' laws of ``transmission``, as in memory) and their shapes
    searched on the ``sample`` (``lap``: called with the name of each stage done)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the subsample's own fit: its warnings are not the record's
        reference = identify(model, sample).estimate
    weights = reference.weights if reference.method == "wls" else 1.0 / reference.channel_variance
    candidates = tuple(default_candidates(model) + coupling_candidates(model, transmission, train=sample)
                       if candidates is None else candidates)
    blocks, rejected = candidate_blocks(model, candidates)
    lap("subsample_pass")
    shapes, failed = shape_search(model, blocks, sample, weights)
    lap("shape_search")
    blocks = {index: block for index, block in blocks.items() if index not in failed}
    order = sorted(blocks)
    plan = pickle.dumps(([blocks[i].effect for i in order], [shapes[i] for i in order]))
    return StreamedCandidates({i: blocks[i] for i in order}, shapes, {**rejected, **failed}, len(candidates),
                       ColumnLayout.build(model, [blocks[i] for i in order]), plan)
