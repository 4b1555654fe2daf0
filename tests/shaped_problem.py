"""The simulated problem the shape-search tests share: a 3-joint PUMA whose truth holds a tanh Coulomb friction
(smoothing 0.03 rad/s) the declared viscous model lacks, two periods of a random Fourier motion at 250 Hz."""

from __future__ import annotations

from dataclasses import dataclass

from dynamics.effects.linear import CoulombFriction
from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel, build_model
from dynamics.robot import RobotModel
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.estimators.effect_blocks import Block, States
from estimation.estimators.separable_least_squares import FixedPart
from oed.fourier import random_fourier

__all__ = ["ShapedProblem", "counting_evaluations", "shaped_problem"]


@dataclass(frozen=True)
class ShapedProblem:
    """The robot, the declared model, its fixed part on the record, the record's states, and the record."""

    robot: RobotModel
    model: IdentificationModel
    fixed: FixedPart
    states: States
    record: Measurements


def shaped_problem(*, kept: bool = False) -> ShapedProblem:
    """The problem, its states kept along the search (``States(kept=True)``) when asked."""
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", ("viscous", CoulombFriction(smoothing=0.03)))
    theta = true_parameters(truth, seed=0, coulomb=[8.0, 5.0, 3.0])
    record = simulate(truth, theta, random_fourier(robot, seed=3), noise={"tau1": 0.2, "tau2": 0.2, "tau3": 0.1},
                      seed=3, rate_hz=250, periods=2)
    model = build_model(robot, "internal", "viscous")
    fixed = FixedPart.from_arrays(model.evaluate_base(record.q, record.dq, record.ddq), record.channels(model.channels))
    states = States(record.q, record.dq, record.ddq, kept=kept)
    return ShapedProblem(robot, model, fixed, states, record)


def counting_evaluations(block: Block) -> list[int]:
    """``block`` with its row functions counting their evaluations: the count, ``[n]``, updated as they run."""
    calls = [0]
    for name in ("row_columns_function", "row_jacobian_function"):
        function = getattr(block, name)

        def counted(*arguments, function=function):
            calls[0] += 1
            return function(*arguments)
        setattr(block, name, counted)
    return calls
