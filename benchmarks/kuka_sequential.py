"""The sequential design on the 7-joint KUKA LWR4+ URDF (``../shared/data/kuka_lwr4/kuka_lwr4.urdf``): a synthetic
first experiment (rigid body, viscous and Coulomb ``tanh`` friction on joint 2, torque noise 0.5 N·m, a random
excitation at 100 Hz over 10 s), the model identified on it, and the next experiment designed for the whole model.

Run: ``python -m benchmarks.kuka_sequential [--starts 8] [--max-iter 150]`` (prints the design's time).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.identification.fit import identify
from estimation.identification.identified_model import IdentifiedModel
from estimation.identification.model_file import ModelFile, RobotSource, model_file_document
from estimation.preprocessing.plan import Preprocessing
from oed.bounds import JointBounds
from oed.excitation import DesignSettings
from oed.fourier import random_fourier
from oed.sequential.next_experiment import NextExperiment, design_next

URDF = Path(__file__).resolve().parents[2] / "shared" / "data" / "kuka_lwr4" / "kuka_lwr4.urdf"


def kuka_case(urdf: Path = URDF):
    """The KUKA's identified model and its first record."""
    robot = load_robot(urdf=urdf)
    model = build_model(robot, "internal", "viscous")
    theta = true_parameters(model, seed=0)
    trajectory = random_fourier(robot, seed=3, frequency_hz=0.2, fill=0.5)
    noise = {channel: 0.5 for channel in model.channels}
    record = simulate(model, theta, trajectory, rate_hz=100.0, periods=2, noise=noise, seed=1)
    result = identify(model, [record], covariance="classical")
    source = RobotSource.from_description(robot, builtin=None, urdf=urdf, joints=None)
    document = model_file_document(result, robot=source, preprocessing=Preprocessing("measured").to_dict())
    return IdentifiedModel(ModelFile.from_dict(document)), record


def kuka_design(starts: int = 8, max_iter: int = 150, settings: DesignSettings | None = None) -> NextExperiment:
    model, record = kuka_case()
    bounds = JointBounds.from_robot(model.robot, ddq_max=[5.0] * model.robot.n_joints, scale=0.9)
    # IPOPT alone, as `oed design --from` runs it (sqp_after=None: the sampled objective jumps with sign(dq))
    return design_next(model, record, bounds=bounds, starts=starts, seed=0,
                       settings=settings or DesignSettings(max_iter=max_iter, sqp_after=None))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--starts", type=int, default=8)
    parser.add_argument("--max-iter", type=int, default=150)
    args = parser.parse_args()
    started = time.perf_counter()
    result = kuka_design(args.starts, args.max_iter)
    elapsed = time.perf_counter() - started
    print(f"KUKA LWR4+ sequential design, {args.starts} starts: {elapsed:.1f} s (design {result.design.total_time_s:.1f} s, "
          f"build {result.design.build_time_s:.1f} s); "
          + ", ".join(f"{s.status} {s.iterations} it {s.time_s:.1f} s" for s in result.design.starts))
    print(result.summary())


if __name__ == "__main__":
    main()
