"""IPOPT handing each design start to an SQP method (``DesignSettings.sqp_after``): the designs against
IPOPT alone, reproducibility, when it is used, the setting and the CLI option."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dynamics.robots import load_robot
from oed.cli import main
from oed.excitation import DesignSettings, ExcitationDesign, design_excitation
from oed.design_solver import sqp_solver


@pytest.fixture(scope="module")
def puma():
    return load_robot("puma560", joints=3)


@pytest.fixture(scope="module")
def handed(puma):
    return ExcitationDesign(puma, "combined")


@pytest.fixture(scope="module")
def alone(puma):
    return ExcitationDesign(puma, "combined", settings=DesignSettings(sqp_after=None))


def test_the_hand_over_designs_as_well_as_ipopt_alone(puma, handed, alone):
    """Same 4 starts: the best criterion at least as good (within 0.01 of −log det over 5 000
    samples), every start a success, and the SQP method did run (more iterations than the hand-over)."""
    with_sqp = design_excitation(puma, problem=handed, starts=4, seed=0)
    without = design_excitation(puma, problem=alone, starts=4, seed=0)
    assert with_sqp.criterion_value <= without.criterion_value + 0.01
    assert all(start.success for start in with_sqp.starts)
    assert any(start.iterations > handed.settings.sqp_after for start in with_sqp.starts)
    assert with_sqp.trajectory.metadata["solver"]["sqp_after"] == 20
    assert without.trajectory.metadata["solver"]["sqp_after"] is None


def test_a_start_gives_the_same_result_whatever_was_solved_before(handed):
    """CasADi's qpOASES hot-starts each QP from the previous one: a solver kept across starts made a
    start's result depend on the starts before it (it took 28 iterations once, 74 the next time)."""
    generator = np.random.default_rng(0)
    first, second = handed.random_start(generator), handed.random_start(generator)
    before = handed.solve(second, 1)
    handed.solve(first, 0)
    after = handed.solve(second, 1)
    assert after.iterations == before.iterations and after.status == before.status
    np.testing.assert_array_equal(after.x, before.x)


def test_only_smooth_criteria_and_enough_iterations_hand_over(puma):
    assert ExcitationDesign(puma, "combined").hands_over
    assert not ExcitationDesign(puma, "combined", criterion="cond").hands_over
    assert not ExcitationDesign(puma, "combined", criterion="mineig").hands_over
    assert not ExcitationDesign(puma, "combined", settings=DesignSettings(sqp_after=None)).hands_over
    assert not ExcitationDesign(puma, "combined", settings=DesignSettings(max_iter=20)).hands_over


@pytest.mark.parametrize("value", [-1, 2.5, True, "20"])
def test_bad_sqp_after_is_refused(value):
    with pytest.raises(ValueError, match="sqp_after"):
        DesignSettings(sqp_after=value)


def test_building_the_sqp_method_prints_nothing(handed, capfd):
    """qpOASES prints its licence banner on the process's standard output whatever its printLevel."""
    A, _, _ = handed.constraint_matrix(handed.constraint_times())
    sqp_solver(handed.cost_function(), A, tol=1e-4, max_iter=10, verbose=False)
    print("after", flush=True)
    assert capfd.readouterr().out == "after\n"


def test_cli_sqp_after_none_runs_ipopt_alone_and_bad_values_fail(tmp_path, capsys):
    out = tmp_path / "traj.json"
    assert main(["design", "--joints", "3", "--model", "internal", "--starts", "1", "--sqp-after", "none",
                 "--out", str(out), "--quiet"]) == 0
    assert json.loads(out.read_text())["solver"]["sqp_after"] is None
    with pytest.raises(SystemExit) as error:
        main(["design", "--joints", "3", "--sqp-after", "-3", "--out", str(tmp_path / "other.json"), "--quiet"])
    assert error.value.code == 2
    assert "non-negative integer or none" in capsys.readouterr().err
