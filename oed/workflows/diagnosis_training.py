"""The streamed diagnosis's training errors against the recording (issue 34: errors against the samples as
recorded), measured as the in-memory diagnosis measures them, block by block.

The streamed diagnosis's training sums hold, on the Fourier path, one averaged period per file (its torques averaged
over the periods too), and, for a file resampled onto a uniform grid (jittered stamps, stalls), torques interpolated
onto the grid: the errors from these sums are not those of the recording. :func:`recorded_training` measures the
training errors of every model the report names (the declared model ``before``, the adopted model ``after``, each
candidate of the default answer, the runner-up) in one more pass over the training files
(:func:`estimation.streaming.recorded_errors.recorded_training_errors`: every sample of the whole periods with the
Fourier fit of the averaged period at its instant; a resampled file at its recorded stamps), each model's prediction
as its model file makes it (shaped laws at their fixed shapes). The sums' errors of a Fourier fit stay in the
report as ``mse_filtered`` (:func:`averaged_errors`).
"""

from __future__ import annotations

import functools
import time
import warnings
from collections.abc import Mapping
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from dynamics.runtime.progress import step
from estimation.consistent.model_selection import ModelSelection
from estimation.diagnosis.results import Diagnosis
from estimation.identification.identified_model import IdentifiedModel
from estimation.identification.model_file import ModelFile, summed_model_file_document
from estimation.identification.subtracted_load import SubtractedLoad
from estimation.identification.validation import ChannelErrors
from oed.workflows.model_files import robot_source
from oed.workflows.options import RecordOptions

if TYPE_CHECKING:  # the streamed path's modules: imported when it runs
    from estimation.streaming.recorded_errors import Predictor

__all__ = ["averaged_errors", "averaged_sums", "recorded_training", "summed_unconstrained"]


class _Prediction:
    """A model file's prediction at other base-parameter vectors: without shaped laws its model's own prediction,
    else its regressor (shaped columns at the file's shapes) evaluated once a block for the vectors asked one after
    the other; ``slot`` holds one regressor, of whichever model asked last (shared by the models of one pass: a
    block's regressor of one model at a time in memory)."""

    def __init__(self, document: dict[str, Any], slot: dict[str, Any]) -> None:
        self.model = IdentifiedModel(ModelFile.from_dict(document))
        self.slot = slot

    def at(self, theta: Any) -> Predictor:
        vector = np.asarray(theta, dtype=float)
        if not self.model.shape:  # no shaped law: the model's own prediction (no regressor held)
            return functools.partial(self.model.model.predict, vector)

        def predict(q, dq, ddq):
            if self.slot.get("model") is not self or self.slot.get("block") is not q:
                self.slot.clear()  # the regressor before freed first
                self.slot.update(model=self, block=q, Y=self.model.regressor(q, dq, ddq))
            return self.slot["Y"] @ vector

        return predict


def summed_unconstrained(selection: ModelSelection) -> Any:
    """The unconstrained fit behind a streamed diagnosis's answer (a
    :class:`~estimation.diagnosis.results.SummedFit`): the chosen one, or the one the consistent fit starts from
    (:attr:`~estimation.consistent.model_selection.ModelSelection.unconstrained` of fits from sums)."""
    return selection.candidate(selection.chosen if selection.chosen != "consistent" else selection.base).fit


def recorded_training(args: RecordOptions, diagnosis: Diagnosis, selection: ModelSelection | None,
                      plan: Mapping[str, Any], chunk_size: int, *, load: SubtractedLoad | None = None
                      ) -> tuple[Diagnosis, ModelSelection | None, dict[str, Any] | None]:
    """``diagnosis`` and ``selection`` (the streamed ones) with their training errors against the channels as
    recorded and ``n_samples`` the recorded samples (module docstring), where the training sums do not hold the
    recording (the Fourier path) or a training file was resampled; unchanged otherwise, or where the loader drops
    rows the streamed grid interpolates. ``plan``: the model files' preprocessing. The third item: on the Fourier
    path, the sums' errors against the averaged period by the report's entry (:func:`averaged_errors`), else
    ``None``. ``load``: the load the logged torques lack, which the run added back: each prediction less it, as
    ``oed predict`` makes it (:func:`estimation.streaming.recorded_errors.less_load`)."""
    streaming = diagnosis.streaming or {}
    files = streaming.get("files") or []
    fourier = averaged_sums(streaming)
    if not fourier and not any(record.get("resampled_from") is not None for record in files):
        return diagnosis, selection, None
    from estimation.streaming.recorded_errors import less_load, recorded_training_errors

    robot = robot_source(diagnosis.model.robot, args)
    slot: dict[str, Any] = {}  # the predictors asked in order, model by model: each regressor once a block
    declared = _Prediction(summed_model_file_document(diagnosis.model, diagnosis.before.estimate, robot=robot,
                                                      preprocessing=dict(plan)), slot)
    final = _Prediction(summed_model_file_document(diagnosis.final_model(), diagnosis.after.estimate, robot=robot,
                                                   preprocessing=dict(plan), shape=diagnosis.final_shape()), slot)
    predictors: dict[Any, Predictor] = {"before": declared.at(diagnosis.before.estimate.values),
                                        "after": final.at(diagnosis.after.estimate.values)}
    fitted = [] if selection is None else [candidate for candidate in selection.candidates if candidate.fit is not None]
    answered = final  # the candidates' model: the adopted one, or on a repeat that model with the plain law completed
    behind = None if selection is None else summed_unconstrained(selection)
    if behind is not None and behind.model is not diagnosis.final_model():
        answered = _Prediction(summed_model_file_document(behind.model, behind.estimate, robot=robot,
                                                          preprocessing=dict(plan), shape=diagnosis.final_shape()),
                               slot)
    for candidate in fitted:
        predictors["candidate", candidate.name] = answered.at(candidate.fit.estimate.values)
    runner_up = diagnosis.runner_up
    if runner_up is not None:
        rival = _Prediction(summed_model_file_document(runner_up.model, runner_up.fit, robot=robot,
                                                       preprocessing=dict(plan), shape=diagnosis.runner_up_shape()), slot)
        predictors["runner_up"] = rival.at(runner_up.fit.values)
    # each prediction's delay between torques and motion, as its model file holds it (oed predict moves the motion by it)
    delays = {"before": declared.model.delay, "after": final.model.delay,
              **{("candidate", candidate.name): answered.model.delay for candidate in fitted}}
    if runner_up is not None:
        delays["runner_up"] = rival.model.delay
    clock = time.perf_counter()
    with step(f"training errors against the recording: a pass over {len(args.data)} training file(s)"), \
            warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the files' findings were said on the first pass
        counted = recorded_training_errors(
            diagnosis.model, less_load(diagnosis.model, predictors, load), args.data, files, chunk_size=chunk_size, cutoff_hz=streaming.get("cutoff_hz"),
            decimation=int(plan.get("decimation", 1)), held_torques=bool(plan.get("held_torques", False)),
            frequency_hz=streaming.get("frequency_hz"), harmonics=int(streaming.get("harmonics") or 5), delays=delays,
            average=streaming.get("average_periods", "auto"))
    if counted is None:
        return diagnosis, selection, None
    errors, count = counted
    seconds = {**streaming.get("seconds", {}), "training_errors_pass": round(time.perf_counter() - clock, 3)}
    averaged = None if not fourier else {
        "before": diagnosis.before.train.mse, "after": diagnosis.after.train.mse,
        "runner_up": None if runner_up is None else dict(runner_up.train_mse),
        "candidates": {candidate.name: candidate.fit.train.mse for candidate in fitted}}
    before = replace(diagnosis.before, train=ChannelErrors(errors["before"], count))
    after = replace(diagnosis.after, train=ChannelErrors(errors["after"], count))
    if runner_up is not None:
        runner_up = replace(runner_up, train_mse=dict(errors["runner_up"]))
    diagnosis = replace(diagnosis, before=before, after=after, runner_up=runner_up,
                        streaming={**streaming, "seconds": seconds})
    if selection is not None:
        measured = {candidate.name: replace(candidate.fit, train=ChannelErrors(errors["candidate", candidate.name],
                                                                                count))
                    for candidate in selection.candidates if candidate.fit is not None}
        refit = selection.consistent
        if refit is not None and selection.base in measured \
                and refit.unconstrained is selection.candidate(selection.base).fit:  # its price against the same errors
            measured["consistent"] = replace(measured["consistent"], unconstrained=measured[selection.base])
        selection = replace(selection, candidates=tuple(
            replace(candidate, fit=measured[candidate.name]) if candidate.name in measured else candidate
            for candidate in selection.candidates))
    return diagnosis, selection, averaged


def averaged_sums(streaming: Mapping[str, Any]) -> bool:
    """Whether a streamed diagnosis's training sums (``streaming``, its document's) hold averaged periods: the
    Fourier path, and a file whose periods were averaged (a file of the Fourier path fitted at its every sample,
    ``periods_averaged`` 0, sums the samples read, as the filter path does)."""
    if streaming.get("frequency_hz") is None:
        return False
    return any(record.get("periods_averaged", 1) != 0 for record in streaming.get("files") or [{}])


def averaged_errors(document: dict[str, Any], averaged: Mapping[str, Any]) -> None:
    """Beside each training ``mse`` of a streamed diagnosis on the Fourier path (measured against the recording,
    :func:`recorded_training`), the sums' error against the averaged period as ``mse_filtered`` (``document`` in
    place: ``train.before``, ``train.after``, ``train.chosen``, ``runner_up.train``, ``consistent.train``;
    ``model_selection.candidates[].train_mse_filtered``), as the streamed ``oed identify`` reports both."""
    candidates = averaged.get("candidates") or {}
    entries = [(document["train"].get("before"), averaged.get("before")),
               (document["train"].get("after"), averaged.get("after")),
               ((document.get("runner_up") or {}).get("train"), averaged.get("runner_up")),
               ((document.get("consistent") or {}).get("train"), candidates.get("consistent"))]
    chosen = document["train"].get("chosen")
    if isinstance(chosen, dict):
        entries.append((chosen, candidates.get(chosen.get("name"))))
    for entry, mse in entries:
        if isinstance(entry, dict) and mse is not None:
            entry["mse_filtered"] = dict(mse)
    for candidate in (document.get("model_selection") or {}).get("candidates", ()):
        mse = candidates.get(candidate.get("name"))
        candidate["train_mse_filtered"] = None if mse is None else dict(mse)
    document["train"]["against"] = ("mse: the channels as recorded, every sample of the training files' whole periods "
                                    "(the Fourier fit of their averaged period at each instant, as in memory); "
                                    "mse_filtered: the averaged period the fit was summed on")
