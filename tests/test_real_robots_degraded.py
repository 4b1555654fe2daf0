"""The four real robots' logs degraded as a user's would be (issue 34): the default ``oed identify`` and
``oed diagnose``, then ``oed predict`` on the degraded test record's recorded samples, against the plain
least-squares fit on the same degraded records (benchmarks/bench_real_degraded.py: the degradations, the plain fit
reading the same files, the comparison).

Held per case: no verb exits on its defaults, or, where the records cannot support the verb, it exits with a
message naming the problem and what would work; each joint within 1.3x the plain fit's test MSE and the mean of the
joints' ratios at most 1.0x; ``oed predict`` reproduces the error the verb reported (relative 1e-6).

The combinations run here are those that matter and stay affordable (about fifteen minutes on two cores): every
degradation on EMPS (seconds each: the reading of every defect, the refusals' messages), and on the arms the
records cut short (KUKA, Panda: what the validation record can still tell apart), the lower rates (Panda at
50 Hz, the TX40's 5 kHz at 100 Hz) and the TX40's blank rows (motor-side columns: every verb exited before). Left out here, each two to six minutes per verb on an arm, measured in the
benchmark's table (benchmarks/README.md, "Real robots' logs degraded as a user's would be"): the arms' jitter,
dropped, stalled and blank rows, units line, torque offset and gain, position offset and validation cases.
A measured miss is a strict xfail holding its figures."""

from __future__ import annotations

import numpy as np
import pytest

from tests.conftest import shared_data

pytestmark = [pytest.mark.realdata, pytest.mark.slow]

RELATIVE = 1e-6

#: a verb that exits on its defaults where the records cannot support it: (robot or None for any, degradation,
#: verb) → what its message must say (the problem and the option that works)
REFUSED = {
    ("no validation", "diagnose"): "--validate",
    ("validation = training", "identify"): "or leave out --validate",
    ("validation = training", "diagnose"): "another experiment",
}

#: measured misses (benchmarks/README.md, the degraded logs' table): strict xfails holding their figures
MISSES = {
    ("panda", "short"): "training cut to 4.6 s, validation to 2 s: identify joint 4 1.64x the plain fit; diagnose "
                        "mean of the joints 1.45x, joint 1 4.61x (both chose WLS, within the 2 s validation "
                        "record's sampling error of the consistent fit: 0.042 +- 0.031 and 0.031 +- 0.024, reported). "
                        "The test sweeps joint 1 over 1.95 rad, the training and validation over the same 1.0 rad: "
                        "the unconstrained fits' predicted parameter variance is 0.23 N2m2 larger on the test than "
                        "on the training record, the consistent fit's 0.05, and the validation record's equals the "
                        "training record's, so no score on it sees the difference (h-shortval2); diagnose's joint 1: "
                        "a ripple of period 2.0 rad fitted on that 1.0 rad arc. On a reference motion (the training "
                        "motion replayed over the description's joint limits, h-reach) wls and the consistent fit "
                        "differ 17-19x more than on the validation record (identify 0.075 -> 1.41, diagnose 0.082 -> "
                        "1.30, in the criterion's units; 2.5x on the Panda at 100 Hz, where wls must stay); the "
                        "band variance alone ranks identify's right (reach score 1.31 against 1.76) but diagnose's "
                        "wrong (consistent +0.99, wls +0.35)",
}

CASES = ([("emps", degradation) for degradation in (
    "short", "100 Hz", "50 Hz", "jitter", "dropped", "stall", "NaN rows", "units header", "torque offset",
    "torque gain", "position offset", "no validation", "validation = training")]
    + [("kuka", "short"), ("panda", "short"), ("panda", "50 Hz"), ("tx40", "100 Hz"), ("tx40", "NaN rows")])


def _marks(robot: str, degradation: str) -> list:
    reason = MISSES.get((robot, degradation))
    return [] if reason is None else [pytest.mark.xfail(strict=True, reason=reason)]


@pytest.mark.parametrize("robot,degradation", [pytest.param(robot, degradation, id=f"{robot}-{degradation}",
                                                            marks=_marks(robot, degradation))
                                               for robot, degradation in CASES])
def test_the_defaults_predict_a_degraded_log_as_well_as_a_plain_fit_on_it(robot, degradation, tmp_path):
    shared_data()
    from benchmarks.bench_real_degraded import compare_degraded, line

    outcome = compare_degraded(robot, degradation, tmp_path)
    print("\n" + "\n".join(line(robot, degradation, outcome)))
    for verb, run in outcome["verbs"].items():
        expected = REFUSED.get((degradation, verb))
        if expected is not None:
            assert run["exit"] != 0 and expected in run["message"], (verb, run["message"])
            continue
        assert run["exit"] == 0, (verb, run["message"])
        ratio = run["mse"] / run["plain"]
        assert np.all(ratio <= 1.3), (verb, ratio.round(3))
        assert np.mean(ratio) <= 1.0, (verb, ratio.round(3))
        if run["reproduced"] is not None:
            assert run["reproduced"] < RELATIVE, (verb, run["reproduced"])
