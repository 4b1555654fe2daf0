"""The simulated case of the sequential-design proofs: a PUMA 560 (three joints) whose joint 2 has a Stribeck law.

Rigid body and viscous friction (:func:`dynamics.simulation.synthetic.true_parameters`, seed 0) plus, on joint 2,
``(fc + fs exp(−(|dq|/vs)²)) sign(dq)`` with a Stribeck velocity ``vs`` small beside the speeds of a random
excitation, torque noise ``σ`` on every joint: the first experiment (:func:`oed.fourier.random_fourier`, seed 3,
0.2 Hz, two periods at 200 Hz) crosses low speed too quickly to pin ``vs`` down. The records are the model's own
prediction plus white noise (:func:`dynamics.simulation.synthetic.simulate`, the Stribeck columns added at the true
shape), with exact ``dq, ddq``: the identification's error is then the noise's alone, as the predicted standard
deviations assume. Used by ``benchmarks/bench_sequential_design.py`` and ``tests/test_sequential_design.py``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from dynamics.measurements import Measurements
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.estimators.effect_blocks import States
from estimation.identification.fit import identify
from estimation.identification.identified_model import IdentifiedModel
from estimation.identification.model_file import ModelFile, RobotSource, model_file_document
from estimation.identification.shaped import shaped_blocks
from estimation.preprocessing.plan import Preprocessing
from oed.fourier import random_fourier

RATE_HZ = 200.0
PERIODS = 2


@dataclass(frozen=True)
class StribeckCase:
    """The truth: Stribeck coefficients and velocity on joint 2, the torque noise, the law as a spec."""

    fc: float = 1.0
    fs: float = 1.0
    vs: float = 0.02
    noise: float = 1.0
    law: str = "stribeck:velocity@2"

    @property
    def robot(self):
        return load_robot("puma560", joints=3)

    @property
    def friction(self) -> str:
        return f"viscous,{self.law}"

    def first_trajectory(self):
        return random_fourier(self.robot, seed=3)

    def record(self, trajectory, seed: int, periods: int = PERIODS) -> Measurements:
        """One noisy record of the true robot along ``trajectory`` (noise seed ``seed``)."""
        robot = self.robot
        declared = build_model(robot, "internal", "viscous")
        theta = true_parameters(declared, seed=0)
        noise = {f"tau{joint}": self.noise for joint in (1, 2, 3)}
        data = simulate(declared, theta, trajectory, rate_hz=RATE_HZ, periods=periods, noise=noise, seed=seed)
        blocks, _ = shaped_blocks(build_model(robot, "internal", "viscous,stribeck:velocity@2"))
        block = blocks[0]
        tau = data.tau.copy()
        columns = block.evaluate(States(data.q, data.dq, data.ddq), np.array([self.vs]))
        tau[:, list(block.rows)] += columns @ np.array([self.fc, self.fs])
        return replace(data, tau=tau)

    def model_document(self, records: Sequence[Measurements], friction: str | None = None) -> dict:
        """The ``model_file`` document of the model identified on ``records`` (white-noise covariance)."""
        model = build_model(self.robot, "internal", friction or self.friction)
        result = identify(model, list(records), covariance="classical")
        return model_file_document(result, robot=RobotSource("puma560[3]", "puma560", 3),
                                   preprocessing=Preprocessing("measured").to_dict())

    def identified(self, records: Sequence[Measurements], friction: str | None = None) -> IdentifiedModel:
        """The model identified on ``records`` (each a segment), as its model file rebuilds it."""
        return IdentifiedModel(ModelFile.from_dict(self.model_document(records, friction)))
