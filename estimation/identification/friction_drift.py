"""Does each joint's friction hold from the training record to the validation record? A drift check.

Gearbox friction changes with temperature: a gear's viscous and Coulomb friction fall as its grease warms up in
the first minutes of motion, and a user's training, validation and test records are often taken minutes apart. A model fitted on a cold training record then predicts a warm record with friction that is no
longer there, and no choice made on the training record can see it.

The check measures it on the validation record, with the rigid body held. With ``θ`` the least-squares fit of the
declared columns on the training record and ``f_j = Y_{j,F_j} θ_{F_j}`` the friction torque that fit predicts on
joint ``j`` (its viscous, Coulomb and Stribeck columns ``F_j``), the two records are fitted together,

``τ = Y θ + d_j [validation] f_j``   (one ``d_j`` per joint, on the validation rows of its own channel only),

the extra columns taken at the training fit's friction (one linearisation: the joint fit then moves ``θ`` by the
validation record's share only). ``s_j = 1 + d_j`` is the friction's scale on the validation record against the
training record's. Its standard error is the batch-means sandwich of the joint fit
(:mod:`estimation.uncertainty.batch_means`: residuals correlated in time, batches that restart at each record's
first sample), so it holds the noise of both records and what the model misses along the motion. A joint's
drift is marked when ``|d_j|`` exceeds :data:`DRIFT_Z` standard errors (two-sided 1 %, Bonferroni over the
joints): the change's own uncertainty, no threshold on its size. The verbs say it; nothing in the fit changes.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.stats import norm

from dynamics.channels import is_joint_torque
from dynamics.measurements import Measurements
from dynamics.models import IdentificationModel, ModelKind
from estimation.data.channel_mask import channel_mean, masked_equations
from estimation.data.segments import segment_slices
from estimation.uncertainty.batch_means import batch_length, batch_means

__all__ = ["DRIFT_ALPHA", "FRICTION_SYMBOLS", "FrictionDrift", "check_friction_drift", "drift_z"]

#: the family-wise level of the check over a robot's joints (two-sided; Bonferroni)
DRIFT_ALPHA = 0.01
#: the parameter symbols of a joint's friction (viscous, Coulomb, Stribeck) whose scale the check measures
FRICTION_SYMBOLS = ("fv", "fc", "fs")
#: the training record's contiguous blocks whose friction scales measure how much the scale moves between motions
BLOCKS = 10
#: at most this many samples of each record enter the fit (evenly spaced rows)
MAX_SAMPLES = 6000


def drift_z(n_joints: int) -> float:
    """The standard errors beyond which a joint's drift is marked: two-sided :data:`DRIFT_ALPHA` over
    ``n_joints`` joints (Bonferroni)."""
    return float(norm.ppf(1.0 - DRIFT_ALPHA / (2.0 * max(n_joints, 1))))


@dataclass(frozen=True)
class FrictionDrift:
    """Each joint's friction on the validation record against the training record's.

    Attributes
    ----------
    joints
        The joints checked (those with friction columns), by name.
    scale, std
        The friction's scale on the validation record (1: as on the training record) and its standard error: the
        sampling one and the spread between motions combined, ``√(sampling² + between²)``.
    friction_rms
        The root mean square of the friction torque the training fit predicts on the validation record, per joint
        (what the scale multiplies).
    """

    joints: tuple[str, ...]
    scale: NDArray[np.float64]
    std: NDArray[np.float64]
    friction_rms: NDArray[np.float64]
    sampling: NDArray[np.float64] | None = None  # the joint fit's batch-means standard error
    between: NDArray[np.float64] | None = None  # the scale's spread between the training record's blocks
    #: the validation MSE per joint of the training fit, and of it with the friction scaled to the validation record's
    #: (cross-fitted halves: each sample predicted by the scale fitted on the other half)
    held_mse: NDArray[np.float64] | None = None
    refitted_mse: NDArray[np.float64] | None = None

    @property
    def z(self) -> NDArray[np.float64]:
        """``(s − 1) / σ`` per joint."""
        return (self.scale - 1.0) / np.where(self.std > 0, self.std, np.inf)

    @property
    def marked(self) -> NDArray[np.bool_]:
        """Per joint: the change exceeds :func:`drift_z` standard errors."""
        return np.abs(self.z) > drift_z(len(self.joints))

    def to_dict(self) -> dict:
        """``result.json``'s ``friction_drift``: per joint the scale, its standard error, ``z`` and whether it is
        marked, with the level used."""
        return {"method": "friction scale on the validation record, the rigid body held (batch-means standard "
                          "error of the two records fitted together)",
                "alpha": DRIFT_ALPHA, "z_limit": drift_z(len(self.joints)),
                "joints": {name: {"scale": float(s), "std": float(e), "std_sampling": float(a),
                                  "std_between_motions": float(b), "z": float(z), "marked": bool(m),
                                  "friction_rms": float(r), "validation_mse_training_friction": float(h),
                                  "validation_mse_validation_friction": float(v)}
                           for name, s, e, a, b, z, m, r, h, v in zip(
                               self.joints, self.scale, self.std, self._sampling, self._between, self.z, self.marked,
                               self.friction_rms, self._mse(self.held_mse), self._mse(self.refitted_mse))}}

    def _mse(self, values: NDArray[np.float64] | None) -> NDArray[np.float64]:
        return np.full(len(self.joints), np.nan) if values is None else values

    @property
    def _sampling(self) -> NDArray[np.float64]:
        return self.std if self.sampling is None else self.sampling

    @property
    def _between(self) -> NDArray[np.float64]:
        return np.zeros_like(self.std) if self.between is None else self.between

    def message(self) -> str | None:
        """The warning when a joint's friction drifted, else ``None``."""
        if not self.marked.any():
            return None
        parts = []
        for name, scale, std in zip(np.asarray(self.joints)[self.marked], self.scale[self.marked],
                                    self.std[self.marked]):
            change = "lower" if scale < 1.0 else "higher"
            parts.append(f"{name} {abs(1.0 - scale):.0%} {change} (scale {scale:.3f} ± {std:.2g})")
        lower = bool(np.all(self.scale[self.marked] < 1.0))
        saved = ""
        if self.held_mse is not None and self.refitted_mse is not None:
            held, refitted = self.held_mse[self.marked].sum(), self.refitted_mse[self.marked].sum()
            saved = (f" (the validation record's own friction predicts its other half with "
                     f"{1.0 - refitted / held:.0%} less error on these joints)") if held > 0 else ""
        cause = ("a gearbox warming up between the records?" if lower else
                 "a gearbox cooling down, or a load or lubrication change between the records?")
        return (f"friction differs between the training and the validation record beyond its standard error: "
                f"{', '.join(parts)}{saved}; {cause} The model holds the training record's friction, and a test record "
                "taken at another time may differ again: record the training motion after the robot has warmed up "
                "(a few minutes of motion), or take the records back to back")

    def lines(self) -> list[str]:
        """The summary's line: each joint's scale, marked ones flagged."""
        shown = ", ".join(f"{name} {scale:.3f} ± {std:.2g}{' (drift)' if mark else ''}"
                          for name, scale, std, mark in zip(self.joints, self.scale, self.std, self.marked))
        return [f"friction on the validation record against the training record's (scale): {shown}"]


def friction_columns(model: IdentificationModel) -> dict[int, list[int]]:
    """Per joint (0-based) the indices of its friction parameters (:data:`FRICTION_SYMBOLS`) among the model's."""
    pattern = re.compile(rf"^({'|'.join(FRICTION_SYMBOLS)})(\d+)$")
    columns: dict[int, list[int]] = {}
    for index, name in enumerate(model.parameter_names):
        found = pattern.match(name)
        if found:
            columns.setdefault(int(found.group(2)) - 1, []).append(index)
    return columns


def _rows(record: Measurements) -> NDArray[np.int64]:
    return np.unique(np.linspace(0, record.n_samples - 1, min(record.n_samples, MAX_SAMPLES)).astype(int))


def _segments(record: Measurements, rows: NDArray[np.int64]) -> list[tuple[int, int]]:
    """The segments of ``record`` (its recorded pieces) in the rows kept."""
    found = []
    for piece in segment_slices(record):
        first, last = np.searchsorted(rows, piece.start), np.searchsorted(rows, piece.stop)
        if last > first:
            found.append((int(first), int(last)))
    return found or [(0, rows.shape[0])]


def check_friction_drift(model: IdentificationModel, train: Measurements, validation: Measurements | None
                         ) -> FrictionDrift | None:
    """Each joint's friction scale on ``validation`` against ``train`` (module docstring), or ``None`` when there is
    nothing to check: no validation record, a model of the base wrench, channels other than the joint torques, or
    no friction columns."""
    channels = model.channels
    if validation is None or model.kind is ModelKind.EXTERNAL \
            or not all(map(is_joint_torque, channels)):
        return None
    columns = {joint: found for joint, found in friction_columns(model).items() if f"tau{joint + 1}" in channels}
    if not columns:
        return None
    joints = sorted(columns)
    regressors, torques, segments = [], [], []
    offset = 0
    scale = None
    for record in (train, validation):
        rows = _rows(record)
        measured = record.channels(channels)[rows]
        scale = np.sqrt(channel_mean((measured - channel_mean(measured)) ** 2, measured)) if scale is None else scale
        # a channel's masked samples (estimation.data.channel_mask): their equations out, the others' kept
        Y, measured, _ = masked_equations(model.evaluate(record.q[rows], record.dq[rows], record.ddq[rows]), measured)
        regressors.append(Y)
        torques.append(measured)
        segments += [(offset + start, offset + stop) for start, stop in _segments(record, rows)]
        offset += rows.shape[0]
    Y_train, Y_valid = regressors
    weights = 1.0 / np.where(scale > 0, scale, 1.0) ** 2  # each channel in its own units: no joint dominates
    n_params = Y_train.shape[2]
    theta = _weighted_lstsq(Y_train, torques[0], weights)[0]
    n_train = Y_train.shape[0]
    extra = np.zeros((n_train + Y_valid.shape[0], len(channels), len(joints)))
    friction_rms = np.empty(len(joints))
    for k, joint in enumerate(joints):
        channel = channels.index(f"tau{joint + 1}")
        friction = Y_valid[:, channel, columns[joint]] @ theta[columns[joint]]
        extra[n_train:, channel, k] = friction
        friction_rms[k] = float(np.sqrt(np.mean(friction**2)))
    X = np.concatenate([np.concatenate([Y_train, Y_valid], axis=0), extra], axis=2)
    tau = np.concatenate(torques, axis=0)
    estimate, normal = _weighted_lstsq(X, tau, weights)
    residual = tau - np.einsum("ncp,p->nc", X, estimate)
    inverse = np.linalg.pinv(normal, rcond=1e-12)
    score_rows = np.einsum("ncp,nc->np", X, residual * weights[None, :])  # per sample: Σ_c w_c r_c X_c
    length = batch_length(residual.T, weights, segments)
    middle = batch_means(score_rows, length, segments)
    covariance = inverse @ middle @ inverse
    drift = estimate[n_params:]
    std = np.sqrt(np.maximum(np.diag(covariance)[n_params:], 0.0))
    between = np.array([_between_blocks(Y_train[:, channels.index(f"tau{joint + 1}")], torques[0][:, channels.index(
        f"tau{joint + 1}")], theta, columns[joint], length) for joint in joints])
    usable = friction_rms > 0
    held, refitted = _cross_fitted(Y_valid, torques[1], theta, [channels.index(f"tau{joint + 1}") for joint in joints],
                                   [columns[joint] for joint in joints])
    return FrictionDrift(tuple(model.robot.joint_names[joint] for joint in np.asarray(joints)[usable]),
                         1.0 + drift[usable], np.sqrt(std**2 + between**2)[usable], friction_rms[usable],
                         std[usable], between[usable], held[usable], refitted[usable])


def _cross_fitted(Y: NDArray, tau: NDArray, theta: NDArray, channels: list[int], columns: list[list[int]]
                  ) -> tuple[NDArray, NDArray]:
    """Per joint, the validation MSE of the training fit (``θ``) and of the same fit with its friction scaled to
    the validation record's, each sample predicted by the scale fitted on the record's other half (two halves in
    time, cross-fitted): the friction drift as a candidate model, judged on samples its scale did not see."""
    halves = np.array_split(np.arange(tau.shape[0]), 2)
    held, refitted = np.empty(len(channels)), np.empty(len(channels))
    for k, (channel, found) in enumerate(zip(channels, columns)):
        friction = Y[:, channel, found] @ theta[found]
        residual = tau[:, channel] - Y[:, channel] @ theta
        scaled = np.empty_like(residual)
        for fitted, scored in ((halves[0], halves[1]), (halves[1], halves[0])):
            energy = float(friction[fitted] @ friction[fitted])
            drift = float(friction[fitted] @ residual[fitted]) / energy if energy > 0 else 0.0
            scaled[scored] = residual[scored] - drift * friction[scored]
        held[k], refitted[k] = float(np.mean(residual**2)), float(np.mean(scaled**2))
    return held, refitted


def _between_blocks(Y: NDArray, tau: NDArray, theta: NDArray, columns: list[int], length: int) -> float:
    """How much one joint's friction scale moves between the parts of the training record itself (:data:`BLOCKS`
    contiguous blocks, each one motion, all at one time): the between-block standard deviation ``τ`` of the
    scales fitted on each block to the training fit's residual, beyond their own sampling spread (DerSimonian and
    Laird's moment estimate, Controlled Clinical Trials 7, 1986). A friction law that does not hold the joint's
    friction at every speed moves the scale from one motion to the next with no change in time; the validation
    record's scale is compared with the training record's within this spread too."""
    friction = Y[:, columns] @ theta[columns]
    residual = tau - Y @ theta
    scales, variances = [], []
    for rows in np.array_split(np.arange(tau.shape[0]), BLOCKS):
        f, r = friction[rows], residual[rows]
        energy = float(f @ f)
        if energy <= 0.0:
            continue
        scale = float(f @ r) / energy
        scores = (f * (r - scale * f))[:, None]
        variances.append(float(batch_means(scores, length)[0, 0]) / energy**2)
        scales.append(scale)
    if len(scales) < 2:
        return 0.0
    scales_, weights = np.asarray(scales), 1.0 / np.maximum(np.asarray(variances), 1e-300)
    mean = float(weights @ scales_ / weights.sum())
    q = float(weights @ (scales_ - mean) ** 2)
    denominator = float(weights.sum() - (weights**2).sum() / weights.sum())
    return float(np.sqrt(max(0.0, (q - (len(scales) - 1)) / denominator))) if denominator > 0 else 0.0


def _weighted_lstsq(Y: NDArray, tau: NDArray, weights: NDArray) -> tuple[NDArray, NDArray]:
    """The channel-weighted least-squares estimate of ``tau ≈ Y θ`` (``Y``: samples × channels × parameters) from
    its normal equations, and their matrix ``Yᵀ W Y``."""
    root = np.sqrt(weights)
    A = (Y * root[None, :, None]).reshape(-1, Y.shape[2])
    normal = A.T @ A
    return np.linalg.lstsq(normal, A.T @ (tau * root[None, :]).reshape(-1), rcond=1e-12)[0], normal
