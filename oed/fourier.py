"""Periodic excitation trajectories: finite Fourier series per joint (PUMA paper, eq. 18).

.. math::
    q_i(t) = q_{0,i} + \\sum_{l=1}^{N} \\frac{a_{i,l}}{ω_f l} \\sin(ω_f l t) - \\frac{b_{i,l}}{ω_f l} \\cos(ω_f l t)

    \\dot q_i(t) = \\sum_l a_{i,l} \\cos(ω_f l t) + b_{i,l} \\sin(ω_f l t)

    \\ddot q_i(t) = \\sum_l - a_{i,l} ω_f l \\sin(ω_f l t) + b_{i,l} ω_f l \\cos(ω_f l t)

Each joint has ``2 N + 1`` parameters (11 for the paper's 5 harmonics at 0.2 Hz). The decision
vector of the design problem stacks them **joint by joint** as ``[q0_i, a_i1..a_iN, b_i1..b_iN]``;
:func:`unpack` and :meth:`FourierTrajectory.to_vector` are the only places that know this order
(``casadi.reshape`` is column-major: keep reshapes here, not scattered through the optimiser).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import casadi
import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.preprocessing.fourier_series import evaluate_series
from dynamics.robot import RobotModel
from dynamics.runtime.output_files import atomic_output, json_text


#: most samples :meth:`FourierTrajectory.sample` returns
MAX_SAMPLES = 50_000_000


@dataclass(frozen=True)
class FourierTrajectory:
    """A periodic trajectory of ``n`` joints with ``N`` harmonics of ``frequency_hz``.

    Attributes
    ----------
    frequency_hz
        Fundamental frequency ``f`` (``ω_f = 2π f``), Hz; the period is ``1/f``.
    q0
        ``(n,)`` offsets.
    a, b
        ``(n, N)`` coefficients in the convention of eq. 18 (velocity amplitudes, rad/s).
    joint_names
        Names of the joints.
    metadata
        Whatever the producer recorded (model, criterion, cost, bounds, solver…), kept on JSON
        round trips.
    """

    frequency_hz: float
    q0: NDArray[np.float64]
    a: NDArray[np.float64]
    b: NDArray[np.float64]
    joint_names: tuple[str, ...] = ()
    metadata: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not (np.isfinite(self.frequency_hz) and self.frequency_hz > 0):
            raise ValueError(f"frequency_hz must be positive, got {self.frequency_hz}")
        q0, a, b = (_numbers(values, name) for name, values in (("q0", self.q0), ("a", self.a), ("b", self.b)))
        q0, a, b = q0.reshape(-1), np.atleast_2d(a), np.atleast_2d(b)
        if a.shape != b.shape or a.shape[0] != q0.shape[0]:
            raise ValueError(f"q0 {q0.shape}, a {a.shape} and b {b.shape} must describe the same joints and harmonics")
        for name, values in (("q0", q0), ("a", a), ("b", b)):
            if not np.all(np.isfinite(values)):
                raise ValueError(f"Fourier coefficients {name} hold NaN or inf")
        object.__setattr__(self, "q0", q0)
        object.__setattr__(self, "a", a)
        object.__setattr__(self, "b", b)
        names = tuple(self.joint_names) or tuple(f"joint{i}" for i in range(1, q0.shape[0] + 1))
        if len(names) != q0.shape[0]:
            raise ValueError(f"{len(names)} joint names for {q0.shape[0]} joints")
        object.__setattr__(self, "joint_names", names)
        object.__setattr__(self, "metadata", dict(self.metadata))

    @property
    def n_joints(self) -> int:
        return self.q0.shape[0]

    @property
    def harmonics(self) -> int:
        return self.a.shape[1]

    @property
    def period(self) -> float:
        return 1.0 / self.frequency_hz

    def evaluate(self, t: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """``q, dq, ddq`` at times ``t``, each ``(len(t), n)`` (eq. 18)."""
        return evaluate_series(self.frequency_hz, self.q0, self.a, self.b, t)

    def sample(self, rate_hz: float = 1000.0, periods: int = 1) -> tuple[NDArray[np.float64], ...]:
        """``t, q, dq, ddq`` on a uniform grid over whole periods (end point excluded)."""
        if not (np.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"rate_hz must be a positive finite number, got {rate_hz}")
        if isinstance(periods, bool) or not isinstance(periods, (int, np.integer)) or periods < 1:
            raise ValueError(f"periods must be a whole number of periods, at least 1, got {periods!r}")
        samples = periods * rate_hz / self.frequency_hz
        if not 1 <= samples <= MAX_SAMPLES:
            raise ValueError(f"{periods} period(s) of {self.frequency_hz:g} Hz at {rate_hz:g} Hz are {samples:.3g} "
                             f"samples; between 1 and {MAX_SAMPLES:.0e} can be sampled")
        count = int(round(samples))
        t = np.arange(count) / rate_hz
        return (t, *self.evaluate(t))

    def to_vector(self) -> NDArray[np.float64]:
        """Decision vector, joint by joint ``[q0_i, a_i., b_i.]``."""
        return np.concatenate([np.concatenate([[q0], a, b]) for q0, a, b in zip(self.q0, self.a, self.b)])

    @classmethod
    def from_vector(
        cls, vector: ArrayLike, n_joints: int, harmonics: int, frequency_hz: float, **kwargs: Any
    ) -> FourierTrajectory:
        block = np.asarray(vector, dtype=float).reshape(n_joints, 2 * harmonics + 1)  # row-major: joint by joint
        return cls(frequency_hz, block[:, 0], block[:, 1 : 1 + harmonics], block[:, 1 + harmonics :], **kwargs)

    def to_dict(self) -> dict[str, Any]:
        """The JSON document: ``frequency_hz, harmonics, q0, a, b, joint_names`` plus metadata keys."""
        document = dict(self.metadata)
        document.update(
            frequency_hz=self.frequency_hz,
            harmonics=self.harmonics,
            q0=self.q0.tolist(),
            a=self.a.tolist(),
            b=self.b.tolist(),
            joint_names=list(self.joint_names),
        )
        return document

    @classmethod
    def from_dict(cls, document: Mapping[str, Any]) -> FourierTrajectory:
        if not isinstance(document, Mapping):
            raise ValueError(f"a trajectory document is a JSON object with frequency_hz, q0, a, b; got {type(document).__name__}")
        missing = [key for key in ("frequency_hz", "q0", "a", "b") if key not in document]
        if missing:
            raise ValueError(f"trajectory document lacks {', '.join(missing)}")
        metadata = {key: value for key, value in document.items() if key not in ("frequency_hz", "harmonics", "q0", "a", "b", "joint_names")}
        frequency = document["frequency_hz"]
        if isinstance(frequency, bool) or not isinstance(frequency, (int, float)):
            raise ValueError(f"trajectory frequency_hz must be a number, got {frequency!r}")
        names = document.get("joint_names", ())
        if names is None:
            names = ()
        if isinstance(names, str) or not isinstance(names, (list, tuple)) or not all(isinstance(n, str) for n in names):
            raise ValueError(f"trajectory joint_names must be a list of names, got {names!r}")
        trajectory = cls(float(frequency), document["q0"], document["a"], document["b"], tuple(names), metadata)
        harmonics = document.get("harmonics", trajectory.harmonics)
        if isinstance(harmonics, bool) or not isinstance(harmonics, int):
            raise ValueError(f"trajectory harmonics must be an integer, got {harmonics!r}")
        if harmonics != trajectory.harmonics:
            raise ValueError(f"trajectory says {harmonics} harmonics but a, b hold {trajectory.harmonics}")
        return trajectory

    def save(self, path: str | Path) -> None:
        """Write the JSON document of :meth:`to_dict` (strict JSON, atomically)."""
        with atomic_output(path) as stream:
            stream.write(json_text(self.to_dict()))

    @classmethod
    def load(cls, path: str | Path) -> FourierTrajectory:
        path = Path(path)
        try:
            document = json.loads(path.read_text())
        except FileNotFoundError:
            raise FileNotFoundError(f"trajectory file not found: {path}") from None
        except json.JSONDecodeError as error:
            raise ValueError(f"trajectory file {path} is not valid JSON: {error}") from None
        return cls.from_dict(document)


def random_fourier(robot: RobotModel, seed: int, *, frequency_hz: float = 0.2, harmonics: int = 5,
                   fill: float = 0.8) -> FourierTrajectory:
    """A random excitation within the robot's bounds: a baseline against the optimised one, and the motion
    of synthetic experiments (:mod:`dynamics.simulation.synthetic`).

    Coefficients ``a, b`` are standard normal draws (``seed``), ``q0`` the centre of the joint range; the
    coefficients are then scaled so that the excursion of ``q`` about its mean and the peak ``|dq|`` stay
    within ``fill`` of half the joint range and of the velocity limit (over one period, 200 samples a period
    of the highest harmonic).

    Parameters
    ----------
    robot
        The robot (its joint ranges ``lower, upper`` and ``velocity_limit``).
    seed
        Seed of the coefficients' draws.
    frequency_hz, harmonics
        Fundamental frequency (Hz) and number of harmonics of the series.
    fill
        Fraction of the range and of the velocity limit the motion may use.
    """
    generator = np.random.default_rng(seed)
    n = robot.n_joints
    centre = 0.5 * (robot.lower + robot.upper)
    half_range = 0.5 * (robot.upper - robot.lower)
    a = generator.normal(size=(n, harmonics))
    b = generator.normal(size=(n, harmonics))
    trajectory = FourierTrajectory(frequency_hz, centre, a, b)
    _, q, dq, _ = trajectory.sample(200.0 * frequency_hz * harmonics, 1)
    deviation = np.max(np.abs(q - q.mean(axis=0)), axis=0)
    speed = np.max(np.abs(dq), axis=0)
    scale = fill * np.minimum(half_range / deviation, robot.velocity_limit / speed)
    return FourierTrajectory(frequency_hz, centre, a * scale[:, None], b * scale[:, None])


def _numbers(values: ArrayLike, name: str) -> NDArray[np.float64]:
    if any(isinstance(value, (bool, np.bool_, str)) for value in np.ravel(np.asarray(values, dtype=object))):
        raise ValueError(f"Fourier coefficients {name} must be numbers, got {values!r}")
    try:
        return np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"Fourier coefficients {name} must be numbers in a regular (joints x harmonics) array") from None


def unpack(vector: casadi.SX | casadi.MX, n_joints: int, harmonics: int) -> tuple:
    """Symbolic ``q0 (n,1), a (n,N), b (n,N)`` from the decision vector (joint-by-joint order)."""
    width = 2 * harmonics + 1
    # casadi.reshape is column-major: reshape to (width, n) so that column i is joint i's block
    block = casadi.reshape(vector, width, n_joints).T
    return block[:, 0], block[:, 1 : 1 + harmonics], block[:, 1 + harmonics :]


def basis(frequency_hz: float, harmonics: int, t: ArrayLike) -> dict[str, NDArray[np.float64]]:
    """Sampled basis matrices ``(T, N)`` such that ``q = q0 + Sq a - Cq b`` etc. (eq. 18).

    Keys: ``sin_q = sin/ω``, ``cos_q = cos/ω``, ``cos``, ``sin``, ``sin_dd = -ω sin``, ``cos_dd = ω cos``.
    With them the trajectory is linear in ``(q0, a, b)``, which the design problem exploits.
    """
    t = np.asarray(t, dtype=float).reshape(-1)
    omega = 2 * np.pi * frequency_hz * np.arange(1, harmonics + 1)
    phase = np.outer(t, omega)
    sin, cos = np.sin(phase), np.cos(phase)
    return {
        "sin_q": sin / omega, "cos_q": cos / omega, "cos": cos, "sin": sin,
        "sin_dd": -sin * omega, "cos_dd": cos * omega,
    }


def check_joint_count(trajectory: FourierTrajectory, n_joints: int) -> None:
    if trajectory.n_joints != n_joints:
        raise ValueError(f"trajectory has {trajectory.n_joints} joints, the robot {n_joints}")


def joint_block_names(joint_names: Sequence[str], harmonics: int) -> list[str]:
    """Names of the decision variables, in vector order."""
    return [
        name
        for joint in joint_names
        for name in [f"{joint}.q0"] + [f"{joint}.a{k}" for k in range(1, harmonics + 1)] + [f"{joint}.b{k}" for k in range(1, harmonics + 1)]
    ]
