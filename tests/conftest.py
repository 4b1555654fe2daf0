"""Shared fixtures: paths, random physically valid parameters, joint states; one BLAS thread a test worker."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

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


CHILD_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


class WorkerBlasLimit:
    """One BLAS thread in a pytest-xdist worker, as :mod:`dynamics.runtime.threads` asks of any unit of work run
    beside others in separate processes: ``make test`` runs two workers on two cores, and OpenBLAS's idle threads
    spin. Measured on the shared 2-core machine: a 3000-sample Fourier noise floor took 6.6 s with the default BLAS
    threads against 0.21 s with one (a 333 x 333 Cholesky factorisation 0.096 s against 0.0008 s).

    The processes a worker starts (``python -m oed`` in the CLI and documentation tests, the notebooks' kernels)
    inherit one thread through the environment (:data:`CHILD_THREAD_VARIABLES`, where the user set none): measured,
    the documentation snippets and notebooks took 90.6 s with their children's default threads and 81.9 s with one."""

    def __init__(self) -> None:
        self.limiter: threadpool_limits | None = None
        self.children_set: list[str] = []

    def hold_children(self) -> None:
        self.children_set = [name for name in CHILD_THREAD_VARIABLES if name not in os.environ]
        os.environ.update({name: "1" for name in self.children_set})

    def lift_children(self) -> None:
        for name in self.children_set:
            os.environ.pop(name, None)
        self.children_set = []

    def hold(self) -> None:
        if self.limiter is None:
            self.limiter = threadpool_limits(limits=1, user_api="blas")

    def lift(self) -> None:
        if self.limiter is not None:
            limiter, self.limiter = self.limiter, None
            limiter.restore_original_limits()


@pytest.fixture(scope="session", autouse=True)
def worker_blas_limit() -> Iterator[WorkerBlasLimit]:
    """Held for the whole session in an xdist worker (``PYTEST_XDIST_WORKER``); a plain ``pytest`` run keeps the
    library's default threads."""
    limit = WorkerBlasLimit()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        limit.hold()
        limit.hold_children()
    try:
        yield limit
    finally:
        limit.lift()
        limit.lift_children()


@pytest.fixture
def default_blas_threads(worker_blas_limit: WorkerBlasLimit) -> Iterator[None]:
    """The BLAS library's own thread counts for one test (the worker's limit lifted, then held again): for the
    tests of the library's thread budgets, which must see a limit to one come and go."""
    held = worker_blas_limit.limiter is not None
    worker_blas_limit.lift()
    try:
        yield
    finally:
        if held:
            worker_blas_limit.hold()
