"""The time base chosen on the validation record: the samples at their stamps, or on the regular clock the stamps
jitter around.

A log with irregular stamps is resampled by them (:func:`estimation.data.loading.uniform_grid`), right when each
sample was taken at its stamp. A logger that stamps a sample when it *arrives* writes receive times: resampling by
them moves each position by its speed times the stamp's error, a noise no filter removes (``benchmarks/README.md``,
h-jitter: the EMPS records with moved stamps, 1.22x the plain fit, 0.52x when t is rewritten as the regular clock).
The positions say which clock the samples followed (:func:`estimation.data.sampling_clock.clock_roughness`); the
answer that counts is the error on another motion, so the two time bases are candidates of the preprocessing
choice, scored like the derivatives on the validation record (issue 34: every candidate of every choice scored on
the same samples).

**When.** Only where the evidence calls for it (:func:`receive_times_evidence`): a record of the training or
validation data resampled by its stamps, whose positions are at least
:data:`~estimation.data.sampling_clock.RECEIVE_TIMES_RATIO` times smoother on a regular clock (the real KUKA
LWR4+: 2.8–4.7; stamps moved as a receiving logger's: 10–113). Elsewhere (regular stamps; the real Panda, 0.97–1.03;
simulated logs sampled at their jittered stamps, below 1) the stamps are kept and nothing is scored twice: the
second clock doubles the derivative choice's cost, and the positions already say the stamps are the instants.

**Same samples.** On the regular clock (:func:`estimation.data.sampling_clock.on_regular_clock`) each recorded
row keeps its values and gets its instant on the clock: nothing is interpolated, the recorded torques never. Each
clock's derivative candidates are scored on the validation record's recorded rows (the same rows, the same
recorded torques: only the instants of the states differ), and both clocks' candidates are rescored together
(:func:`~estimation.identification.preprocessing_on_validation.rescored`: one criterion over the pooled
candidates). The smallest score wins; an exact tie keeps the stamps (what the file says).

**Not a candidate** when a segment's stamps give no regular clock (a stamp half a step or more from its instant:
a dropped row or a stall inside the segment; :func:`~estimation.data.sampling_clock.regular_clock`), or when the
derivatives are not chosen on a validation record of another motion (measured derivatives, the user's
``--cutoff``, no validation record): the stamps are then kept, as before. The streamed path (files read in blocks)
makes the same choice (:func:`oed.workflows.memory_path.streamed_time_base`: the sources read on their regular
clock, :class:`estimation.streaming.time_base.RegularClock`), but where a training file is cut at its holds
(:data:`STREAMED_TIME_BASE`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from dynamics.measurements import Measurements
from estimation.data.sampling_clock import RECEIVE_TIMES_RATIO, on_regular_clock, receive_times_ratio
from estimation.identification.preprocessing_on_validation import TIE_DIGITS, rescored
from estimation.preprocessing.plan import Preprocessing

__all__ = ["STREAMED_TIME_BASE", "choose_time_base", "receive_times_evidence", "regular_segments"]

#: what the streamed path (files read in blocks) says of the time base (``not_computed.time_base``) where a training
#: file is cut at its holds: there it keeps the stamps (elsewhere it scores the regular clock as memory does,
#: :func:`oed.workflows.memory_path.streamed_time_base`)
STREAMED_TIME_BASE = ("the samples at their stamps: a training file cut at its holds is read in parts, and the "
                      "regular clock of a part is scored in memory only (where the stamps look like receive times, "
                      "said by a ReceiveTimesWarning)")


def receive_times_evidence(segments: Sequence[Measurements]) -> float | None:
    """The largest receive-times ratio (:func:`~estimation.data.sampling_clock.receive_times_ratio`) over
    ``segments`` when it reaches :data:`~estimation.data.sampling_clock.RECEIVE_TIMES_RATIO`, else ``None``: the
    regular clock is then not a candidate."""
    ratios = [ratio for ratio in map(receive_times_ratio, segments) if ratio is not None]
    if not ratios or max(ratios) < RECEIVE_TIMES_RATIO:
        return None
    return float(max(ratios))


def regular_segments(segments: Sequence[Measurements]) -> tuple[Measurements, ...] | None:
    """Every segment on its regular clock (:func:`~estimation.data.sampling_clock.on_regular_clock`), ``None``
    when one resampled segment gives none."""
    moved = [on_regular_clock(segment) for segment in segments]
    if any(segment is None for segment in moved):
        return None
    return tuple(segment for segment in moved if segment is not None)


def choose_time_base(at_stamps: Preprocessing, on_clock: Preprocessing, channels: Sequence[str],
                     ratio: float) -> Preprocessing:
    """The plan of the time base whose best derivative candidate predicts the validation record best (module
    docstring), both clocks' candidates rescored together, with :attr:`~Preprocessing.time_base` and both scores
    (:attr:`~Preprocessing.time_base_evidence`). ``at_stamps``, ``on_clock``: the plans chosen on the validation
    record with the records at their stamps and on their regular clock (each with its evidence,
    ``selection == "validation"``); ``ratio``: :func:`receive_times_evidence`. The stamps are kept when either was
    not chosen on the validation record, or when the two were not scored on as many recorded samples."""
    stamps_evidence = () if at_stamps.evidence is None else at_stamps.evidence.validation
    clock_evidence = () if on_clock.evidence is None else on_clock.evidence.validation
    if (at_stamps.evidence is None or on_clock.evidence is None or at_stamps.evidence.selection != "validation"
            or on_clock.evidence.selection != "validation"):
        return at_stamps
    samples = {item.samples for item in (*stamps_evidence, *clock_evidence) if np.isfinite(item.score)}
    if len(samples) != 1:
        return at_stamps
    pooled = rescored([*stamps_evidence, *clock_evidence], channels)
    stamps_score = min((item.score for item in pooled[:len(stamps_evidence)]), default=float("inf"))
    regular_score = min((item.score for item in pooled[len(stamps_evidence):]), default=float("inf"))
    regular = float(f"{regular_score:.{TIE_DIGITS}g}") < float(f"{stamps_score:.{TIE_DIGITS}g}")
    evidence = {"stamps": stamps_score, "regular": regular_score, "ratio": ratio}
    if regular:
        return replace(on_clock, time_base="regular", time_base_evidence=evidence)
    return replace(at_stamps, time_base_evidence=evidence)
