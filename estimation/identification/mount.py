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
motion with 55 % less error while the description's bodies then predicted it 34 times worse, with the search of
the day; the batched search now prefers a 2.5° tilt there, which :data:`WORSE_LIMIT` refuses). The
verbs say it (the mount to write into the URDF), and try the model with the found gravity as a candidate of their
default answer, taken only when it predicts the validation record better
(:mod:`estimation.consistent.mounted_gravity`); the result file then holds that gravity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel, ModelKind, build_model
from estimation.data.channel_mask import whole_rows

__all__ = ["MIN_ANGLE_DEG", "MOUNT_MARK", "WORSE_LIMIT", "MountCheck", "check_mount", "mount_rpy"]

#: the share of the validation error with the description's gravity at or below which another direction is said
MOUNT_MARK = 0.5
#: a channel whose validation error the found direction makes more than this many times the description's keeps it
#: from being said (:attr:`MountCheck.marked`)
WORSE_LIMIT = 1.05
#: a direction closer than this (degrees) to the description's is not said (a model that fits to the rounding)
MIN_ANGLE_DEG = 2.0
#: at most this many samples of each record enter the sums (evenly spaced rows: the check is about the gravity load)
MAX_SAMPLES = 3000
#: directions of the grid over the sphere (a Fibonacci lattice: about 17° apart; the best refined)
GRID = 150
#: the refinement: caps about the best direction so far, of these radii (degrees), :data:`CAP` directions each (about
#: a quarter of the radius apart: each cap holds the last one's spacing)
REFINEMENT = (15.0, 4.0, 1.0, 0.25, 0.06, 0.015)
CAP = 60


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
    #: each channel's validation MSE with the description's gravity and with the found (the fit's channels, in order)
    declared_channel_mse: tuple[float, ...] = ()
    found_channel_mse: tuple[float, ...] = ()
    #: the same without gravity (the torques hold no gravity load: a log of a controller that subtracts its gravity
    #: model, or of torques without gravity): the fit's total and channels' validation MSE, the description's bodies'
    #: (``nan``, ``()``: not computed)
    zero_mse: float = float("nan")
    zero_channel_mse: tuple[float, ...] = ()
    nominal_zero_mse: float = float("nan")

    def explained_channels(self) -> tuple[int, ...]:
        """The channels (indices in the fit's order) whose validation error the gravity said (:attr:`gravity`) brings
        to at most :data:`MOUNT_MARK` of the description's: the loads the mount explains (none unless
        :attr:`marked`)."""
        if not self.marked:
            return ()
        return tuple(index for index, (declared, said) in enumerate(zip(self.declared_channel_mse,
                                                                         self.said_channel_mse))
                     if said <= MOUNT_MARK * declared)

    @staticmethod
    def _holds(mse: float, declared_mse: float, channels: tuple[float, ...], declared_channels: tuple[float, ...],
               nominal: float, nominal_declared: float) -> bool:
        """At most :data:`MOUNT_MARK` of the description's validation error, no channel's more than
        :data:`WORSE_LIMIT` times the description's, and the description's bodies no worse (``nan``: no condition)."""
        worse = any(value > WORSE_LIMIT * declared for declared, value in zip(declared_channels, channels))
        contradicted = bool(nominal > nominal_declared)  # False when either is nan
        return bool(mse <= MOUNT_MARK * declared_mse and not worse and not contradicted)

    @property
    def turned(self) -> bool:
        """Whether the found direction predicts the validation record with at most :data:`MOUNT_MARK` of the error,
        at least :data:`MIN_ANGLE_DEG` from the description's, no channel's error more than :data:`WORSE_LIMIT`
        times the description's (a turned gravity is the whole robot's, and a fault of one joint, a torque logged
        with the opposite sign, found a direction that serves that joint at the others' expense: h-mountdiag), and the
        description's bodies do not contradict it (they predict the validation record no worse with it: h-newuser)."""
        return self.angle_deg >= MIN_ANGLE_DEG and self._holds(
            self.found_mse, self.declared_mse, self.found_channel_mse, self.declared_channel_mse,
            self.nominal_found_mse, self.nominal_declared_mse)

    @property
    def absent(self) -> bool:
        """Whether the torques hold no gravity load: the fit without gravity marked as a direction is (:attr:`turned`:
        half the error or less, no channel worse, the description's bodies no worse without gravity) and, when a
        direction is marked too, predicting the validation record with less error than it."""
        holds = self._holds(self.zero_mse, self.declared_mse, self.zero_channel_mse, self.declared_channel_mse,
                            self.nominal_zero_mse, self.nominal_declared_mse)
        return bool(holds and (not self.turned or self.zero_mse < self.found_mse))

    @property
    def marked(self) -> bool:
        """Whether the check says another gravity than the description's: a turned direction (:attr:`turned`) or none
        (:attr:`absent`)."""
        return self.absent or self.turned

    @property
    def gravity(self) -> NDArray[np.float64]:
        """The gravity said (m/s², base frame): zero when :attr:`absent`, else the found direction."""
        return np.zeros(3) if self.absent else self.found

    @property
    def said_mse(self) -> float:
        """The total validation MSE of the fit with :attr:`gravity`."""
        return self.zero_mse if self.absent else self.found_mse

    @property
    def said_channel_mse(self) -> tuple[float, ...]:
        """Each channel's validation MSE of the fit with :attr:`gravity`."""
        return self.zero_channel_mse if self.absent else self.found_channel_mse

    @property
    def angle_deg(self) -> float:
        """The angle between the found and the declared gravity, degrees."""
        cosine = float(self.found @ self.declared / (np.linalg.norm(self.found) * np.linalg.norm(self.declared)))
        return float(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))))

    def message(self, *, taken: bool = False, subtracted: bool = False) -> str:
        """The warning: the direction found, the error it saves, and the mount to write into the URDF; ``taken``: the
        answer was fitted with the found gravity (it validated better, :mod:`estimation.consistent.mounted_gravity`),
        else it keeps the description's; ``subtracted``: the answer is the model of a log that subtracts the
        description's gravity torque (:mod:`estimation.identification.subtracted_load`)."""
        taken_words = ("the answer is fitted with the found gravity (it predicts the validation record better: the "
                       "model selection's reason gives the scores), which the result file holds for predict and export"
                       if taken else "this fit keeps the description's gravity")
        if subtracted:
            taken_words = ("the answer is the model of a log less the description's gravity torque (fitted to the "
                           "torques with it added back; it predicts the validation record better: the model "
                           "selection's reason gives the scores), which the result file's subtracted holds for "
                           "predict and export")
        if self.absent:
            return (f"the torques hold no gravity load: the fit without gravity predicts the validation record with "
                    f"{1.0 - self.zero_mse / self.declared_mse:.0%} less error than with the description's. A "
                    "controller that subtracts its gravity model before logging, or a logger of the torques without "
                    "gravity? Log the torques with gravity to identify the bodies' gravity load; " + taken_words)
        roll, pitch, yaw = mount_rpy(self.found)
        shown = ", ".join(f"{value:.3g}" for value in self.found)
        return (f"the torques' gravity load points elsewhere than the robot description says: gravity along "
                f"({shown}) m/s² in the base frame ({self.angle_deg:.0f}° from the description's) predicts the "
                f"validation record with {1.0 - self.found_mse / self.declared_mse:.0%} less error. A robot on a "
                "wall, on the ceiling or off level? Give the mount in the URDF: a link \"world\" and a fixed joint "
                f"from it to the base link, <origin xyz=\"0 0 0\" rpy=\"{roll:.4f} {pitch:.4f} {yaw:.4f}\"/> (a yaw "
                "about gravity is free: any gives the same loads); " + taken_words)


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


def _cap(centre: NDArray, radius: float) -> NDArray[np.float64]:
    """:data:`CAP` directions evenly spread over the cap of angular ``radius`` about the unit vector ``centre`` (a
    Fibonacci lattice on the cap, turned onto ``centre``), ``centre`` the first."""
    index = np.arange(CAP)
    polar = np.arccos(1.0 - (1.0 - np.cos(radius)) * index / (CAP - 1))
    azimuth = np.pi * (1.0 + 5.0**0.5) * index
    local = np.column_stack([np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)])
    frame = np.linalg.svd(centre[None, :])[2]  # rows: centre (up to sign) and two directions square to it
    frame = np.vstack([frame[1:], frame[0] * np.sign(frame[0] @ centre)])
    return local @ frame


def _grams(model: IdentificationModel, others, record: Measurements, samples: int
           ) -> tuple[NDArray, NDArray, NDArray]:
    """``(G, h, c)``: each channel's Gram sums of the four regressors ``[Y_0, Y_x, Y_y, Y_z]`` (``G[k, a, b] =
    Y_{a,k}ᵀ Y_{b,k}``, ``h[k, a] = Y_{a,k}ᵀ τ_k``, ``c[k] = τ_kᵀ τ_k`` on channel ``k``) over at most
    ``samples`` evenly spaced samples of ``record``; their sums over ``k`` are the whole record's. ``Y_0``: the
    declared ``model`` without gravity; ``Y_x``: its rigid-body columns at rest (the gravity load along the declared
    direction), ``Y_y``, ``Y_z``: those of ``others`` (the rigid body alone, gravity along two directions square to
    it); the other columns' gravity terms are zero (no effect depends on gravity)."""
    rows = np.unique(np.linspace(0, record.n_samples - 1, min(record.n_samples, samples)).astype(int))
    q, dq, ddq = record.q[rows], record.dq[rows], record.ddq[rows]
    tau = record.channels(model.channels)[rows]
    rest = np.zeros_like(q)
    rigid = others[0].n_parameters  # the standard parameters come first in every model's columns
    blocks = np.zeros((4,) + (q.shape[0], model.n_channels, model.n_parameters))
    blocks[1, :, :, :rigid] = model.evaluate(q, rest, rest)[:, :, :rigid]
    blocks[0] = model.evaluate(q, dq, ddq)
    blocks[0, :, :, :rigid] -= blocks[1, :, :, :rigid]
    for index, other in enumerate(others, start=2):
        blocks[index, :, :, :rigid] = other.evaluate(q, rest, rest)
    count, samples, channels, width = blocks.shape
    stacked = np.ascontiguousarray(blocks.transpose(2, 1, 0, 3)).reshape(channels, samples, count * width)
    G = np.matmul(stacked.transpose(0, 2, 1), stacked).reshape(channels, count, width, count, width)
    h = np.einsum("knc,nk->kc", stacked, tau).reshape(channels, count, width)
    return G.transpose(0, 1, 3, 2, 4), h, np.einsum("nk,nk->k", tau, tau)


def _solve(A: NDArray, b: NDArray) -> NDArray:
    """The least-squares parameters of the normal equations ``A θ = b`` (one or a stack): a ridge of ``1e-10`` of the
    largest diagonal term keeps the parameters gravity leaves unidentified at zero (the standard parameters hold
    combinations no record separates), as a truncated pseudo-inverse would, at a solve's cost."""
    ridge = 1e-10 * np.max(np.diagonal(A, axis1=-2, axis2=-1), axis=-1)
    return np.linalg.solve(A + ridge[..., None, None] * np.eye(A.shape[-1]), b[..., None])[..., 0]


def _scored(u: NDArray, train: tuple, held_out: tuple) -> NDArray:
    """The validation RSS of the least-squares fit on the training sums with gravity along each row of ``u`` (unit
    vectors in the frame of the three gravity regressors, at the magnitude they were built with; or one)."""
    weights = np.concatenate([np.ones(np.shape(u)[:-1] + (1,)), u], axis=-1)
    pairs = np.einsum("...a,...b->...ab", weights, weights)
    A = np.tensordot(pairs, train[0], axes=([-2, -1], [0, 1]))
    return _rss(weights, _solve(A, np.tensordot(weights, train[1], axes=([-1], [0]))), held_out)


def _rss(weights: NDArray, theta: NDArray, held_out: tuple) -> NDArray:
    """The RSS on the record of ``held_out`` (its sums over the channels) of the parameters ``theta`` with the
    regressors weighted by ``weights`` (``(1, u)``, ``u`` a unit vector of gravity in the frame of the three gravity
    regressors; one or a stack of each)."""
    G, h, c = held_out
    pairs = np.einsum("...a,...b->...ab", weights, weights)
    return (c - 2.0 * np.einsum("...r,...a,ar->...", theta, weights, h)
            + np.einsum("...r,...rs,...s->...", theta, np.tensordot(pairs, G, axes=([-2, -1], [0, 1])), theta))


def _channel_scores(u: NDArray, train: tuple, held_out: tuple) -> NDArray:
    """Each channel's validation RSS of the fit of :func:`_scored` with gravity along ``u`` (``held_out``: each
    channel's sums)."""
    weights = np.r_[1.0, u]
    theta = _solve(np.einsum("a,b,abrs->rs", weights, weights, train[0]), weights @ train[1])
    G, h, c = held_out
    return (c - 2.0 * np.einsum("kar,a,r->k", h, weights, theta)
            + np.einsum("r,a,b,kabrs,s->k", theta, weights, weights, G, theta))


def check_mount(model: IdentificationModel, train: Measurements, validation: Measurements | None, *,
                samples: int = MAX_SAMPLES) -> MountCheck | None:
    """Gravity's direction that predicts ``validation`` best (module docstring), or ``None`` when there is nothing to
    check: no validation record, a model of the base wrench (its rows hold gravity's direction through the whole
    robot's weight, not the joints' loads), or a description without gravity. ``samples``: at most this many evenly
    spaced samples of each record enter the sums. A sample with a masked channel (:mod:`estimation.data.channel_mask`:
    a clipped sensor's, a held channel's repeat) is left out whole (its sums take a sample's channels together)."""
    robot = model.robot
    magnitude = float(np.linalg.norm(robot.gravity))
    if validation is None or model.kind is ModelKind.EXTERNAL or magnitude == 0.0:
        return None
    train, validation = whole_rows(train), whole_rows(validation)
    declared = np.asarray(robot.gravity, dtype=float) / magnitude
    # the regressors along the declared direction and two square to it: the declared model's rigid-body columns at
    # rest are its gravity load's (no motion, no other load), and two models of the rigid body alone give the others
    across = np.linalg.svd(declared[None, :])[2][1:]
    others = [build_model(robot.with_gravity(magnitude * axis), model.kind, ()) for axis in across]
    frame = np.vstack([declared, across])  # rows: the directions of the three gravity regressors (orthonormal)
    train_sums = tuple(np.sum(part, axis=0) for part in _grams(model, others, train, samples))  # the whole record
    held_sums = _grams(model, others, validation, samples)
    held_full = tuple(np.sum(part, axis=0) for part in held_sums)  # in the model's columns: the nominal bodies' RSS
    # the parameters no gravity direction identifies (every regressor's columns null on them) left out: the sums
    # projected onto the range of the training record's (the fits' solves then the size of what the data identify)
    values, vectors = np.linalg.eigh(np.einsum("aars->rs", train_sums[0]))
    kept = vectors[:, values > 1e-10 * values.max()]
    train_sums = (kept.T @ train_sums[0] @ kept, train_sums[1] @ kept)
    held_sums = (kept.T @ held_sums[0] @ kept, held_sums[1] @ kept, held_sums[2])
    held_totals = tuple(np.sum(part, axis=0) for part in held_sums)
    directions = _sphere(GRID)  # in that frame: the declared direction is (1, 0, 0)
    scores = _scored(directions, train_sums, held_totals)
    best, best_score = directions[int(np.argmin(scores))], float(scores.min())
    for radius in REFINEMENT:  # caps about the best so far
        cap = _cap(best, np.radians(radius))
        cap_scores = _scored(cap, train_sums, held_totals)
        if cap_scores.min() < best_score:
            best, best_score = cap[int(np.argmin(cap_scores))], float(cap_scores.min())
    count = min(validation.n_samples, samples)
    nominal = model.nominal_parameters()
    declared_channels = _channel_scores(np.eye(3)[0], train_sums, held_sums) / count
    found_channels = _channel_scores(best, train_sums, held_sums) / count
    return MountCheck(magnitude * declared, magnitude * (best @ frame),
                      float(_scored(np.eye(3)[0], train_sums, held_totals)) / count,
                      best_score / count,
                      declared_channel_mse=tuple(float(value) for value in declared_channels),
                      found_channel_mse=tuple(float(value) for value in found_channels),
                      nominal_declared_mse=float(_rss(np.r_[1.0, np.eye(3)[0]], nominal, held_full)) / count,
                      nominal_found_mse=float(_rss(np.r_[1.0, best], nominal, held_full)) / count,
                      zero_mse=float(_scored(np.zeros(3), train_sums, held_totals)) / count,
                      zero_channel_mse=tuple(float(value) for value in
                                             _channel_scores(np.zeros(3), train_sums, held_sums) / count),
                      nominal_zero_mse=float(_rss(np.r_[1.0, np.zeros(3)], nominal, held_full)) / count)
