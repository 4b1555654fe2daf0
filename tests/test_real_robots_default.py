"""Real robots (issue 34): the default `oed identify` (then `oed predict`) predicts a test record no choice saw
about as well as a plain Pinocchio least-squares fit of rigid body, viscous and Coulomb friction and offsets, or
better (benchmarks/bench_real_robots.py: the records, the plain fit, the comparison at the recorded samples).

Target of the issue: per joint within 1.3x the plain fit, on the mean at most 1.0x (held here both as the mean of
the per-joint ratios and, where met, as the ratio of the totals). Measured (benchmarks/README.md, "The default
answer on real robots", with the derivatives chosen on the validation record of another motion): KUKA LWR4+ total
0.171x (mean of the joints' ratios 0.224x, worst joint 0.687x), Franka Panda 0.994x (0.929x, 1.031x), EMPS 0.536x:
met, held here; Stäubli TX40 1.019x in total (0.979x on the mean of the joints' ratios, worst joint 1.065x): the
total held here within 1.05x."""

from __future__ import annotations

import numpy as np
import pytest

from tests.conftest import shared_data

pytestmark = [pytest.mark.realdata, pytest.mark.slow]

#: the bound on the total (default / plain) held per robot: the target where it is met, else the measured miss
TOTAL_BOUND = {"kuka": 1.0, "emps": 1.0, "panda": 1.0, "tx40": 1.05}


@pytest.mark.parametrize("robot", sorted(TOTAL_BOUND))
def test_the_default_model_predicts_a_new_record_about_as_well_as_a_plain_fit_or_better(robot, tmp_path):
    shared_data()
    from benchmarks.bench_real_robots import ROBOTS, compare

    outcome = compare(ROBOTS[robot](tmp_path), tmp_path, labels=("default",))
    default, plain = outcome["mse"]["default"], outcome["mse"]["plain OLS"]
    assert default is not None, "the default oed identify failed"
    assert default.sum() <= TOTAL_BOUND[robot] * plain.sum(), (default.round(4), plain.round(4))
    assert np.all(default / plain <= 1.3), (default / plain).round(3)
    assert np.mean(default / plain) <= 1.0, (default / plain).round(3)
