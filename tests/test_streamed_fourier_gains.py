"""The streamed verbs (``--chunk-size``) try an unknown gain on each joint's torque on the Fourier path of averaged
periods as memory does (h-streamclock).

Before, the streamed ``oed identify`` said ``not_computed.torque_gains`` there ("its check fits the records, not their
averaged periods") and the streamed ``oed diagnose`` skipped the check without a word, where memory checks the gains
on its prepared records (the averaged period of the training record, every recorded validation sample with the fit's
motion) and, taken, fits the torques divided by them. The check's pass reads exactly those samples streamed
(:func:`estimation.streaming.periods.plan_chunks` with the excitation frequency). The log: the 6-joint PUMA of
:func:`tests.test_streamed_subtracted_load.periodic_compensated_records` with gravity in its torques and each joint's
logged torque times a gain (0.7–1.3), positions only, two whole periods a record.

Compared with memory, as the filter path's tests compare them (:mod:`tests.test_torque_gains`): the gains are fitted
by an iterative Levenberg–Marquardt loop from sums summed in another order, so they agree to about 1e-5 path to path,
not to rounding (measured on this log: 5e-5 on the determined gains of the diagnosis, 2e-11 for identify's; the
diagnosis's validation and test errors 2e-5 apart).
"""

from __future__ import annotations

import json

import pytest

from oed.cli import main
from tests.test_streamed_subtracted_load import PERIODIC_HZ, periodic_compensated_records

#: each joint's gain on its logged torque
GAINS = (0.8, 1.25, 0.9, 1.1, 1.3, 0.7)


def _run(verb: str, folder, train, validate, *options: str) -> dict:
    out = folder / f"{verb}{'-streamed' if options else ''}.json"
    more = ["--friction", "viscous,coulomb,offset"] if verb == "identify" else []
    assert main([verb, "--data", str(train), "--validate", str(validate), "--frequency", str(PERIODIC_HZ), *more,
                 *options, "--out", str(out)]) == 0
    return json.loads(out.read_text())


def _metrics(document: dict, record, folder, name: str) -> dict[str, float]:
    model, metrics = folder / f"{name}-model.json", folder / f"{name}-metrics.json"
    model.write_text(json.dumps(document))
    assert main(["predict", "--model", str(model), "--data", str(record), "--metrics", str(metrics)]) == 0
    return json.loads(metrics.read_text())["mse"]


@pytest.mark.slow  # each verb in memory and streamed on a 6-joint arm (about 2 and 7 minutes)
@pytest.mark.parametrize("verb", ["identify", "diagnose"])
def test_the_streamed_fourier_path_checks_the_torque_gains_as_memory_does(verb, tmp_path, capsys):
    train, validate, test = periodic_compensated_records(tmp_path, compensated=False, gains=GAINS)
    memory = _run(verb, tmp_path, train, validate)
    streamed = _run(verb, tmp_path, train, validate, "--chunk-size", "500")
    capsys.readouterr()
    assert streamed["streaming"]["files"][0]["periods_averaged"] == 2
    assert "torque_gains" not in streamed["not_computed"]
    fitted = [document["torque_gains"] for document in (memory, streamed)]
    assert fitted[0] is not None and fitted[1] is not None, fitted
    assert fitted[1].get("taken", True) == fitted[0].get("taken", True)
    for channel, entry in fitted[0]["channels"].items():
        assert fitted[1]["channels"][channel]["value"] == pytest.approx(entry["value"], rel=1e-3), channel
        assert fitted[1]["channels"][channel]["determined"] == entry["determined"]
    assert streamed["model_file"]["chosen"] == memory["model_file"]["chosen"]
    assert ("torque_gains" in streamed["model_file"]) == ("torque_gains" in memory["model_file"])
    if verb == "diagnose":  # taken on this log: the torques divided by them diagnosed, as in memory
        assert "torque_gains" in memory["model_file"]
        assert [(effect["name"], effect["channels"]) for effect in streamed["effects"]] \
            == [(effect["name"], effect["channels"]) for effect in memory["effects"]]
    reported = streamed["model_file"]["reported"]["validation_mse"]
    measured = _metrics(streamed, validate, tmp_path, "streamed-validation")
    assert max(abs(measured[channel] / reported[channel] - 1.0) for channel in reported) < 1e-6
    errors = [_metrics(document, test, tmp_path, name) for name, document in (("memory", memory),
                                                                              ("streamed", streamed))]
    assert max(abs(errors[1][channel] / errors[0][channel] - 1.0) for channel in errors[0]) < 1e-3, errors
