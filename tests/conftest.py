"""Shared fixtures: paths, random physically valid parameters, joint states."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dynamics.robot import RobotModel, inertial_parameters

TESTS = Path(__file__).resolve().parent
REPOSITORY = TESTS.parent
SHARED_DATA = REPOSITORY.parent / "shared" / "data"


def shared_data(*parts: str) -> Path:
    """A path under ``../shared/data``; skips the test, saying why, when it is absent."""
    path = SHARED_DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"real data not available: {path} is absent (the shared data folder sits beside the checkout)")
    return path


def random_link_parameters(generator: np.random.Generator) -> np.ndarray:
    """Ten standard parameters of a physically valid rigid body (positive mass, triangle inequality)."""
    mass = generator.uniform(0.5, 10.0)
    com = generator.uniform(-0.3, 0.3, 3)
    principal = generator.uniform(0.01, 0.5, 3)
    principal[2] = generator.uniform(abs(principal[0] - principal[1]) + 1e-3, principal[0] + principal[1])
    rotation, _ = np.linalg.qr(generator.normal(size=(3, 3)))
    return inertial_parameters(mass, com, rotation @ np.diag(principal) @ rotation.T)


def random_parameters(robot: RobotModel, seed: int) -> np.ndarray:
    generator = np.random.default_rng(seed)
    return np.concatenate([random_link_parameters(generator) for _ in robot.joints])


def random_states(n_joints: int, n_samples: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    generator = np.random.default_rng(seed)
    return (
        generator.uniform(-np.pi, np.pi, (n_samples, n_joints)),
        generator.normal(0, 2, (n_samples, n_joints)),
        generator.normal(0, 5, (n_samples, n_joints)),
    )


@pytest.fixture
def prismatic_urdf() -> Path:
    return TESTS / "data" / "prismatic_arm.urdf"
