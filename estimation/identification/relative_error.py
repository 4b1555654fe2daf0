"""The criterion of every choice made on a validation record of another motion: each channel's error relative to
the best any candidate reaches on it, averaged over the channels.

The toolkit chooses on a validation record three times (issue 34): the derivatives
(:mod:`estimation.identification.preprocessing_on_validation`), the weighting the consistent fit starts from and
the model among OLS, WLS and the consistent fit (:mod:`estimation.consistent.model_selection`). The channels are in
different units (N·m and N) and of different sizes (a shoulder and a wrist), so the raw sum of the MSE lets the
largest channel decide. The geometric mean over channels, used before, is scale-invariant but lets a candidate
trade one channel's large loss for another's gain: on a torso and arm it took a filter that made joint 2's
error 0.13 times the plain fit's and the torso's 20 times, since ``log 20`` is offset by ``log(1/0.13)`` and a
little more on the other joints.

**Score** (:func:`relative_scores`). For candidates ``k`` with validation MSE ``e[k, c]`` on channel ``c`` (against
the channels as recorded, every candidate on the same samples)::

    score[k] = mean over c of  e[k, c] / min over candidates j of e[j, c]

Each channel counts by its ratio to what the candidates show is reachable on it, as the issue's target counts
each joint by its ratio to a plain fit ("per joint within 1.3x, on the mean at most 1.0x"): the score is 1 only
for a candidate best on every channel, and a candidate ``r`` times worse than the best on one of ``n`` channels
pays ``(r - 1) / n`` however much it gains elsewhere (a gain can only bring its other ratios down to 1). It is a
channel-weighted sum of the MSE with weights ``1 / min_j e[j, c]``: scale-invariant per channel, and the ranking
of two candidates depends on the others only through those per-channel minima, which do not depend on the order
in which the candidates are listed (ties are left to each choice's own fixed rule).

A candidate whose error is not finite on some channel is no candidate (score ``inf``) and sets no minimum. A
channel that some candidate predicts exactly (``min = 0``) counts 1 for the candidates that do and ``inf`` for the
others.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping, Sequence
from typing import TypeVar

import numpy as np

__all__ = ["CRITERION", "relative_scores"]

#: what the scores of the choices made on a validation record are (``criterion`` in ``result.json``)
CRITERION = ("mean over channels of each channel's validation MSE against the channels as recorded, divided by the "
             "smallest any candidate reaches on that channel")

Key = TypeVar("Key", bound=Hashable)


def relative_scores(errors: Mapping[Key, Mapping[str, float] | None], channels: Sequence[str]) -> dict[Key, float]:
    """Each candidate's score (module docstring): the mean over ``channels`` of its MSE over the smallest MSE of
    any candidate on that channel.

    Parameters
    ----------
    errors
        Per candidate (any hashable key), its MSE per channel (``None``: not scored).
    channels
        The channels the score runs over (each must be in every scored candidate's errors).

    Returns
    -------
    dict
        Per candidate, in the order of ``errors``: its score, ``>= 1`` (``1`` only for a candidate best on every
        channel), ``inf`` for a candidate with an error that is not finite or missing.
    """
    channels = tuple(channels)
    if not channels:
        raise ValueError("the score needs at least one channel")
    keys = list(errors)
    table = np.full((len(keys), len(channels)), np.inf)
    for row, key in enumerate(keys):
        mse = errors[key]
        if mse is None:
            continue
        values = np.array([mse.get(channel, np.nan) for channel in channels], dtype=float)
        if np.all(np.isfinite(values)):
            if np.any(values < 0):
                raise ValueError(f"candidate {key!r}: a mean squared error is negative ({dict(zip(channels, values))})")
            table[row] = values
    scored = np.all(np.isfinite(table), axis=1)
    if not np.any(scored):
        return {key: float("inf") for key in keys}
    best = table[scored].min(axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratios = np.where(best > 0, table / np.where(best > 0, best, 1.0), np.where(table == 0, 1.0, np.inf))
    scores = ratios.mean(axis=1)
    return {key: float(scores[row]) if scored[row] else float("inf") for row, key in enumerate(keys)}
