"""Is the robot mounted as its description says? Gravity's direction in the base frame, checked on held-out data.

A URDF places the robot's base in the world by its fixed ``world -> base`` joint; without one, gravity is taken
along the base's ``-z`` (a robot on the floor). An arm on a wall or on the ceiling, or a pedestal off level, then has
gravity loads the model cannot hold: on a simulated PUMA 560 on a wall with a URDF that does not say so, both the
toolkit and a plain least-squares fit predicted joint 1 at 4500 times the noise floor, and ``oed diagnose`` named a
spring on joint 1 where gravity acts (``benchmarks/README.md``, h-unseen8).

The regressor is linear in gravity (Newton-Euler: gravity enters as the base's acceleration ``-g``), so
``Y(q, q̇, q̈; g) = Y(q, q̇, q̈; 0) + Σ_k g_k Y_k(q)`` with ``Y_k = Y(q, q̇, q̈; e_k) − Y(q, q̇, q̈; 0)``, one model per
axis. :func:`check_mount` fits the declared model's columns by least squares on the training record for gravity of
the description's magnitude along each direction of a grid over the sphere (the Gram sums of the four regressors
combined: no sample held per direction), scores each on the validation record, refines the best, and marks it when
it predicts the validation record with at most :data:`MOUNT_MARK` of the error with the description's gravity, and the
description's own bodies (its nominal parameters, no friction) predict the validation record no worse with it than with
the description's gravity. The second condition is the description's word on its own mount: a robot really on a wall
or the ceiling is predicted better by its description turned there; the least-squares fit alone can prefer a turned
gravity for other reasons (on the real KUKA LWR4+, standing on the floor, gravity turned 179° fitted the repeated
motion with 55 % less error while the description's bodies then predicted it 34 times worse). The
verbs say it (the mount to write into the URDF); nothing is changed in the fit: the description is the user's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize

from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel, ModelKind, build_model

__all__ = ["MIN_ANGLE_DEG", "MOUNT_MARK", "MountCheck", "check_mount", "mount_rpy"]

#: the share of the validation error with the description's gravity at or below which another direction is said
MOUNT_MARK = 0.5
#: a direction closer than this (degrees) to the description's is not said (a model that fits to the rounding)
MIN_ANGLE_DEG = 2.0
#: at most this many samples of each record enter the sums (evenly spaced rows: the check is about the gravity load)
MAX_SAMPLES = 3000
#: directions of the grid over the sphere (a Fibonacci lattice: about 12° apart; the best refined)
GRID = 300


@dataclass(frozen=True)
class MountCheck:
    """Gravity's direction in the base frame that predicts the validation record best.

    Attributes
    ----------
    declared, found
        Gravity in the base frame (m/s²): the description's, and the best direction at the same magnitude.
    declared_mse, found_mse
        The total validation MSE of the least-squares fit of the declared columns with each.
    nominal_declared_mse, nominal_found_mse
        The total validation MSE of the description's own bodies (nominal parameters, no friction) with each
        (``nan``: not computed, no condition).
    """

    declared: NDArray[np.float64]
    found: NDArray[np.float64]
    declared_mse: float
    found_mse: float
    nominal_declared_mse: float = float("nan")
    nominal_found_mse: float = float("nan")

    @property
    def marked(self) -> bool:
        """Whether the found direction predicts the validation record with at most :data:`MOUNT_MARK` of the error,
        at least :data:`MIN_ANGLE_DEG` from the description's, and the description's bodies do not contradict it
        (they predict the validation record no worse with it)."""
        contradicted = bool(self.nominal_found_mse > self.nominal_declared_mse)  # False when either is nan
        return bool(self.found_mse <= MOUNT_MARK * self.declared_mse and self.angle_deg >= MIN_ANGLE_DEG
                    and not contradicted)

    @property
    def angle_deg(self) -> float:
        """The angle between the found and the declared gravity, degrees."""
        cosine = float(self.found @ self.declared / (np.linalg.norm(self.found) * np.linalg.norm(self.declared)))
        return float(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))))

    def message(self) -> str:
        """The warning: the direction found, the error it saves, and the mount to write into the URDF."""
        roll, pitch, yaw = mount_rpy(self.found)
        shown = ", ".join(f"{value:.3g}" for value in self.found)
        return (f"the torques' gravity load points elsewhere than the robot description says: gravity along "
                f"({shown}) m/s² in the base frame ({self.angle_deg:.0f}° from the description's) predicts the "
                f"validation record with {1.0 - self.found_mse / self.declared_mse:.0%} less error. A robot on a "
                "wall, on the ceiling or off level? Give the mount in the URDF: a link \"world\" and a fixed joint "
                f"from it to the base link, <origin xyz=\"0 0 0\" rpy=\"{roll:.4f} {pitch:.4f} {yaw:.4f}\"/> (a yaw "
                "about gravity is free: any gives the same loads); this fit keeps the description's gravity")


def mount_rpy(gravity: NDArray[np.float64]) -> tuple[float, float, float]:
    """The URDF ``rpy`` (no yaw: a yaw about gravity changes no load) of a fixed ``world -> base`` joint under which
    gravity ``(0, 0, −|g|)`` in the world is ``gravity`` in the base frame: ``R = Ry(pitch) Rx(roll)`` with
    ``Rᵀ (0, 0, −1) = ĝ = (sin p, −cos p sin r, −cos p cos r)``."""
    u = np.asarray(gravity, dtype=float) / np.linalg.norm(gravity)
    return float(np.arctan2(-u[1], -u[2])), float(np.arcsin(np.clip(u[0], -1.0, 1.0))), 0.0


def _sphere(count: int) -> NDArray[np.float64]:
    index = np.arange(count) + 0.5
    polar = np.arccos(1.0 - 2.0 * index / count)
    azimuth = np.pi * (1.0 + 5.0**0.5) * index
    return np.column_stack([np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)])


def _grams(models, record: Measurements) -> tuple[NDArray, NDArray, float]:
    """``(G, h, c)``: the Gram sums of the four regressors ``[Y_0, Y_x, Y_y, Y_z]`` (``G[a, b] = Y_aᵀ Y_b``,
    ``h[a] = Y_aᵀ τ``, ``c = τᵀ τ``) over at most :data:`MAX_SAMPLES` evenly spaced samples of ``record``."""
    rows = np.unique(np.linspace(0, record.n_samples - 1, min(record.n_samples, MAX_SAMPLES)).astype(int))
    q, dq, ddq = record.q[rows], record.dq[rows], record.ddq[rows]
    tau = record.channels(models[0].channels)[rows].reshape(-1)
    zero = models[0].evaluate(q, dq, ddq)
    blocks = [zero.reshape(-1, zero.shape[2])] + [(model.evaluate(q, dq, ddq) - zero).reshape(-1, zero.shape[2])
                                                  for model in models[1:]]
    G = np.array([[a.T @ b for b in blocks] for a in blocks])
    return G, np.array([a.T @ tau for a in blocks]), float(tau @ tau)


def _scored(u: NDArray, train: tuple, held_out: tuple) -> float:
    """The validation RSS of the least-squares fit on the training sums with gravity along ``u`` (at the
    magnitude the axes' regressors were built with)."""
    weights = np.r_[1.0, u / np.linalg.norm(u)]  # u in the frame of the three gravity regressors
    A = np.einsum("a,b,abrs->rs", weights, weights, train[0])
    return _held_out_rss(u, np.linalg.lstsq(A, weights @ train[1], rcond=1e-10)[0], held_out)


def _held_out_rss(u: NDArray, theta: NDArray, held_out: tuple) -> float:
    """The validation RSS of the parameters ``theta`` with gravity along ``u`` (the fitted ones, or the description's
    nominal ones)."""
    weights = np.r_[1.0, u / np.linalg.norm(u)]
    G, h, c = held_out
    return float(c - 2.0 * theta @ (weights @ h) + theta @ np.einsum("a,b,abrs->rs", weights, weights, G) @ theta)


def check_mount(model: IdentificationModel, train: Measurements, validation: Measurements | None
                ) -> MountCheck | None:
    """Gravity's direction that predicts ``validation`` best (module docstring), or ``None`` when there is nothing to
    check: no validation record, a model of the base wrench (its rows hold gravity's direction through the whole
    robot's weight, not the joints' loads), or a description without gravity."""
    robot = model.robot
    magnitude = float(np.linalg.norm(robot.gravity))
    if validation is None or model.kind is ModelKind.EXTERNAL or magnitude == 0.0:
        return None
    declared = np.asarray(robot.gravity, dtype=float) / magnitude
    # the declared model is gravity along ``declared``; with the one without gravity and those along two directions
    # square to it, the regressors along any direction follow (three models built, not four)
    across = np.linalg.svd(declared[None, :])[2][1:]
    zero = build_model(robot.with_gravity(np.zeros(3)), model.kind, model.effects)
    others = [build_model(robot.with_gravity(magnitude * axis), model.kind, model.effects) for axis in across]
    frame = np.vstack([declared, across])  # rows: the directions of the three gravity regressors (orthonormal)
    train_sums, held_sums = (_grams([zero, model, *others], record) for record in (train, validation))
    directions = _sphere(GRID)  # in that frame: the declared direction is (1, 0, 0)
    scores = np.array([_scored(u, train_sums, held_sums) for u in directions])
    start = directions[int(np.argmin(scores))]
    polar, azimuth = np.arccos(np.clip(start[2], -1.0, 1.0)), np.arctan2(start[1], start[0])

    def unit(angles: NDArray) -> NDArray:
        return np.array([np.cos(angles[1]) * np.sin(angles[0]), np.sin(angles[1]) * np.sin(angles[0]),
                         np.cos(angles[0])])

    refined = minimize(lambda angles: _scored(unit(angles), train_sums, held_sums), [polar, azimuth],
                       method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-12, "maxiter": 400})
    best = unit(refined.x) if refined.fun <= scores.min() else start
    count = min(validation.n_samples, MAX_SAMPLES)
    nominal = model.nominal_parameters()
    return MountCheck(magnitude * declared, magnitude * (best @ frame),
                      _scored(np.eye(3)[0], train_sums, held_sums) / count,
                      min(float(refined.fun), float(scores.min())) / count,
                      _held_out_rss(np.eye(3)[0], nominal, held_sums) / count,
                      _held_out_rss(best, nominal, held_sums) / count)
