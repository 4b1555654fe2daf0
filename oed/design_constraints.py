"""Constraints that let a real robot run an excitation: torque limits, a floor, self-collision (issue #36).

Each constraint is a small object, like the bounds, that the design problem
(:class:`oed.design_problem.ExcitationDesign`) evaluates at its constraint points:

- :meth:`function` is a CasADi ``Function`` ``(q, dq, ddq) -> g`` of one sample whose rows must stay
  ``g ≥ 0``: smooth, so that IPOPT gets exact derivatives by AD;
- :meth:`margins` gives, for a ``(T, n)`` trajectory, the margins in physical units (``≥ 0``: met)
  by an independent computation (Pinocchio and coal for the geometry), as checked on the fine grid
  and written to the design file.

Rules (stated in ``docs/cli/design.md``):

- **torque** (:class:`TorqueLimits`): ``τ = Y(q, dq, ddq) θ_nominal + F_v dq + F_c sign(dq)`` with the
  description's inertials and the URDF's ``<dynamics damping friction>``; inside the optimisation the
  sign is replaced by both signs, ``τ_rb + F_v dq ± F_c ∈ [−τ_max, τ_max]`` (smooth and never looser);
  rows are scaled by ``τ_max``.
- **floor** (:class:`Floor`) and **self-collision** (:class:`SelfCollision`): the shapes are covered
  by spheres (:meth:`dynamics.collision.Primitive.spheres`; a box stays exact: its corners for the
  floor, point–box distances against spheres). All clearances ``h_k`` of one link (floor) or of one
  pair of non-adjacent links (self-collision), less the margin, enter one smooth row
  ``log 2 − log(1 + Σ_k exp(−h_k/λ)) ≥ 0`` (``λ`` = :data:`SMOOTHING_M`), which holds only when
  every ``h_k ≥ 0`` (it keeps up to ``λ log K`` more than the margin where ``K`` clearances are equal).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import casadi
import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.collision import CollisionGeometry, read_collision_geometry
from dynamics.kinematics import joint_frames
from dynamics.mjcf import is_mjcf, mjcf_joint_terms
from dynamics.newton_euler import rigid_body_regressors
from dynamics.robot import RobotModel

#: the length scale λ (m) of the smooth minimum of the geometric constraints
SMOOTHING_M = 0.004
#: default least distance between non-adjacent links (m)
DEFAULT_COLLISION_MARGIN = 0.02


class ConstraintError(ValueError):
    """A constraint that cannot be set up (no effort limits, no collision geometry, a start in collision…)."""


def _smooth_floor(clearances: casadi.SX) -> casadi.SX:
    """``log 2 − log(1 + Σ exp(−h/λ))``: ``≥ 0`` only when every clearance ``h ≥ 0`` (module docstring)."""
    return np.log(2.0) - casadi.log(1 + casadi.sum1(casadi.exp(-clearances / SMOOTHING_M)))


def declared_friction(path: str | Path, robot: RobotModel) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Viscous (``damping``) and Coulomb (``friction``) coefficients of the URDF's ``<dynamics>``, per joint; of an
    MJCF model's joints, ``damping`` and ``frictionloss`` (:func:`dynamics.mjcf.mjcf_joint_terms`)."""
    import pinocchio as pin

    if is_mjcf(path):
        terms = mjcf_joint_terms(path, robot)
        return (np.array([terms[name]["viscous"] for name in robot.joint_names]),
                np.array([terms[name]["coulomb"] for name in robot.joint_names]))

    model = pin.buildModelFromUrdf(str(path))
    return np.asarray(model.damping, dtype=float)[: robot.n_joints], np.asarray(model.friction, dtype=float)[: robot.n_joints]


@dataclass(frozen=True, eq=False)
class TorqueLimits:
    """``|τ| ≤ τ_max`` per joint for the nominal model's torque (module docstring).

    Parameters
    ----------
    robot
        Its joints' ``effort`` limits and standard inertial parameters give ``τ_max`` and ``θ``.
    viscous, coulomb
        ``(n,)`` declared friction (default zero).
    """

    robot: RobotModel
    viscous: ArrayLike | None = None
    coulomb: ArrayLike | None = None
    _cache: dict = field(default_factory=dict, repr=False)

    name = "torque"
    unit = "N·m"

    def __getstate__(self) -> dict:
        """Pickled without the built CasADi functions (rebuilt where unpickled)."""
        return {**self.__dict__, "_cache": {}}

    def __post_init__(self) -> None:
        n = self.robot.n_joints
        effort = np.array([joint.effort for joint in self.robot.joints], dtype=float)
        missing = [joint.name for joint, limit in zip(self.robot.joints, effort) if not np.isfinite(limit)]
        if missing:
            raise ConstraintError(f"--torque-limits: {self.robot.name} has no effort limit for joint(s) "
                                  f"{', '.join(missing)} (URDF <limit effort=...>)")
        for name in ("viscous", "coulomb"):
            value = np.zeros(n) if getattr(self, name) is None else np.asarray(getattr(self, name), float).reshape(-1)
            if value.shape != (n,) or not np.all(np.isfinite(value)) or np.any(value < 0):
                raise ConstraintError(f"{name} friction must be {n} non-negative numbers, got {value}")
            object.__setattr__(self, name, value)
        object.__setattr__(self, "effort", effort)

    @classmethod
    def from_urdf(cls, path: str | Path, robot: RobotModel) -> TorqueLimits:
        """The limits with the URDF's declared friction."""
        return cls(robot, *declared_friction(path, robot))

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(self.robot.joint_names)

    def _rigid_body(self) -> casadi.Function:
        if "tau" not in self._cache:
            regressors = rigid_body_regressors(self.robot)
            tau = casadi.mtimes(regressors.joint, casadi.DM(self.robot.standard_parameters))
            self._cache["tau"] = casadi.Function("nominal_torque", [regressors.q, regressors.dq, regressors.ddq],
                                                 [tau], ["q", "dq", "ddq"], ["tau"])
        return self._cache["tau"]

    def function(self) -> casadi.Function:
        """``(q, dq, ddq) -> g`` (``2n``): ``1 − (τ_rb + F_v dq + F_c)/τ_max`` and ``1 + (τ_rb + F_v dq − F_c)/τ_max``."""
        if "g" not in self._cache:
            n = self.robot.n_joints
            q, dq, ddq = (casadi.SX.sym(name, n) for name in ("q", "dq", "ddq"))
            tau = self._rigid_body()(q, dq, ddq) + casadi.DM(self.viscous) * dq
            effort, coulomb = casadi.DM(self.effort), casadi.DM(self.coulomb)
            g = casadi.vertcat(1 - (tau + coulomb) / effort, 1 + (tau - coulomb) / effort)
            self._cache["g"] = casadi.Function("torque_margin", [q, dq, ddq], [g], ["q", "dq", "ddq"], ["g"])
        return self._cache["g"]

    def torque(self, q: ArrayLike, dq: ArrayLike, ddq: ArrayLike) -> NDArray[np.float64]:
        """``(T, n)`` nominal torque with the Coulomb term's sign (N·m)."""
        q, dq, ddq = (np.atleast_2d(np.asarray(v, dtype=float)) for v in (q, dq, ddq))
        rigid = np.asarray(self._rigid_body().map(q.shape[0])(q.T, dq.T, ddq.T)).T
        return rigid + self.viscous * dq + self.coulomb * np.sign(dq)

    def margins(self, q: ArrayLike, dq: ArrayLike, ddq: ArrayLike) -> NDArray[np.float64]:
        """``(T, n)``: ``τ_max − |τ|`` (N·m)."""
        return self.effort - np.abs(self.torque(q, dq, ddq))

    def describe(self) -> dict[str, Any]:
        return {"effort": self.effort.tolist(), "viscous": self.viscous.tolist(), "coulomb": self.coulomb.tolist(),
                "rule": "nominal inertials + viscous dq ± Coulomb (both signs) within ±effort"}


def _world_points(frames: tuple[casadi.SX, casadi.SX], joint: int, points: NDArray[np.float64]) -> list[casadi.SX]:
    """``points`` (``(k, 3)``, in joint ``joint``'s frame; 0: the base) in the base frame, one 3-vector each."""
    if joint == 0:
        return [casadi.SX(casadi.DM(point)) for point in points]
    R, p = frames
    rotation, origin = R[:, 3 * (joint - 1):3 * joint], p[:, joint - 1]
    return [origin + rotation @ casadi.DM(point) for point in points]


def _world_pose(frames: tuple[casadi.SX, casadi.SX], joint: int,
                placement: NDArray[np.float64]) -> tuple[casadi.SX, casadi.SX]:
    if joint == 0:
        return casadi.SX(casadi.DM(placement[:3, :3])), casadi.SX(casadi.DM(placement[:3, 3]))
    R, p = frames
    rotation, origin = R[:, 3 * (joint - 1):3 * joint], p[:, joint - 1]
    return rotation @ casadi.DM(placement[:3, :3]), origin + rotation @ casadi.DM(placement[:3, 3])


@dataclass(frozen=True, eq=False)
class _GeometricConstraint:
    robot: RobotModel
    geometry: CollisionGeometry
    _cache: dict = field(default_factory=dict, repr=False)

    def __getstate__(self) -> dict:
        """Pickled without the built CasADi functions (rebuilt where unpickled)."""
        return {**self.__dict__, "_cache": {}}

    def _check_geometry(self, option: str) -> None:
        missing = self.geometry.links_without_geometry()
        if missing:
            raise ConstraintError(f"{option}: link(s) {', '.join(missing)} of {self.robot.name} have no collision "
                                  "geometry (URDF <collision>)")

    def _spheres(self, frames, joint: int) -> tuple[list[casadi.SX], list[float], list[tuple[Any, Any, Any]]]:
        """World centres and radii of the sphere covers of joint ``joint``'s non-box shapes, and the world
        pose and half extents of its boxes."""
        centres, radii, boxes = [], [], []
        for index in self.geometry.on_joint(joint):
            primitive = self.geometry.primitives[index]
            if primitive.kind == "box":
                rotation, origin = _world_pose(frames, joint, primitive.placement)
                boxes.append((rotation, origin, primitive))
                continue
            local, r = primitive.spheres()
            centres += _world_points(frames, joint, local)
            radii += list(r)
        return centres, radii, boxes

    def function(self) -> casadi.Function:
        if "g" not in self._cache:
            n = self.robot.n_joints
            q, dq, ddq = (casadi.SX.sym(name, n) for name in ("q", "dq", "ddq"))
            frames = joint_frames(self.robot)(q)
            g = casadi.vertcat(*self._rows(frames))
            self._cache["g"] = casadi.Function(f"{self.name}_margin", [q, dq, ddq], [g], ["q", "dq", "ddq"], ["g"])
        return self._cache["g"]


@dataclass(frozen=True, eq=False)
class Floor(_GeometricConstraint):
    """Every link's collision geometry above the plane ``z = height`` of the base frame."""

    height: float = 0.0
    name = "floor"
    unit = "m"

    def __post_init__(self) -> None:
        if not np.isfinite(self.height):
            raise ConstraintError(f"--floor must be a finite height (m), got {self.height}")
        self._check_geometry("--floor")
        base = self.geometry.on_joint(0)
        if base:
            lowest = self.geometry.lowest_points(np.zeros(self.robot.n_joints))[base]
            if lowest.min() < self.height - 1e-9:
                raise ConstraintError(f"--floor {self.height:g}: the base itself reaches down to z = {lowest.min():.4g} m "
                                      "(its collision geometry crosses the floor)")

    @classmethod
    def from_urdf(cls, path: str | Path, robot: RobotModel, height: float) -> Floor:
        return cls(robot, read_collision_geometry(path, robot), height=float(height))

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(self.geometry.link_names[1:])

    def _rows(self, frames) -> list[casadi.SX]:
        rows = []
        for joint in range(1, self.robot.n_joints + 1):
            centres, radii, boxes = self._spheres(frames, joint)
            heights = [centre[2] - radius - self.height for centre, radius in zip(centres, radii)]
            for rotation, origin, primitive in boxes:
                corners = primitive.corners() - primitive.placement[:3, 3]
                local = corners @ primitive.placement[:3, :3]  # corners in the box frame
                heights += [origin[2] + (rotation @ casadi.DM(corner))[2] - self.height for corner in local]
            rows.append(_smooth_floor(casadi.vertcat(*heights)))
        return rows

    def margins(self, q: ArrayLike, dq: ArrayLike | None = None, ddq: ArrayLike | None = None) -> NDArray[np.float64]:
        """``(T, n)``: exact height of each link's lowest point above the floor (m)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        joints = np.array([primitive.joint for primitive in self.geometry.primitives])
        result = np.empty((q.shape[0], self.robot.n_joints))
        for row, sample in enumerate(q):
            lowest = self.geometry.lowest_points(sample)
            result[row] = [lowest[joints == joint].min() for joint in range(1, self.robot.n_joints + 1)]
        return result - self.height

    def describe(self) -> dict[str, Any]:
        return {"height": self.height, "rule": "sphere covers (boxes: corners) above z = height, smooth minimum "
                f"over each link's points (lambda = {SMOOTHING_M} m)"}


@dataclass(frozen=True, eq=False)
class SelfCollision(_GeometricConstraint):
    """At least ``margin`` between the collision geometries of every pair of non-adjacent links."""

    margin: float = DEFAULT_COLLISION_MARGIN
    name = "self_collision"
    unit = "m"

    def __post_init__(self) -> None:
        if not (np.isfinite(self.margin) and self.margin >= 0):
            raise ConstraintError(f"--collision-margin must be a non-negative distance (m), got {self.margin}")
        self._check_geometry("--self-collision")

    @classmethod
    def from_urdf(cls, path: str | Path, robot: RobotModel, margin: float = DEFAULT_COLLISION_MARGIN) -> SelfCollision:
        return cls(robot, read_collision_geometry(path, robot), margin=float(margin))

    @property
    def pairs(self) -> list[tuple[int, int]]:
        return self.geometry.non_adjacent_pairs()

    @property
    def labels(self) -> tuple[str, ...]:
        names = self.geometry.link_names
        return tuple(f"{names[i]}/{names[j]}" for i, j in self.pairs)

    def _rows(self, frames) -> list[casadi.SX]:
        covers = {joint: self._spheres(frames, joint) for joint in range(self.robot.n_joints + 1)}
        rows = []
        for i, j in self.pairs:
            (centres_i, radii_i, boxes_i), (centres_j, radii_j, boxes_j) = covers[i], covers[j]
            clearances = []
            for a, ra in zip(centres_i, radii_i):
                for b, rb in zip(centres_j, radii_j):
                    clearances.append(casadi.sqrt(casadi.sumsqr(a - b) + 1e-12) - ra - rb - self.margin)
            for centres, radii, boxes in ((centres_i, radii_i, boxes_j), (centres_j, radii_j, boxes_i)):
                for rotation, origin, primitive in boxes:
                    for centre, radius in zip(centres, radii):
                        local = rotation.T @ (centre - origin)
                        outside = casadi.fmax(casadi.fabs(local) - casadi.DM(primitive.half_extents), 0)
                        clearances.append(casadi.sqrt(casadi.sumsqr(outside) + 1e-12) - radius - self.margin)
            for box_a, box_b in ((a, b) for a in boxes_i for b in boxes_j):  # box–box: one box's sphere cover
                rotation, origin, primitive = box_b
                local_centres, local_radii = box_a[2].spheres()
                for point, radius in zip(local_centres - box_a[2].placement[:3, 3], local_radii):
                    centre = box_a[1] + box_a[0] @ casadi.DM(point @ box_a[2].placement[:3, :3])
                    local = rotation.T @ (centre - origin)
                    outside = casadi.fmax(casadi.fabs(local) - casadi.DM(primitive.half_extents), 0)
                    clearances.append(casadi.sqrt(casadi.sumsqr(outside) + 1e-12) - radius - self.margin)
            rows.append(_smooth_floor(casadi.vertcat(*clearances)))
        return rows

    def margins(self, q: ArrayLike, dq: ArrayLike | None = None, ddq: ArrayLike | None = None) -> NDArray[np.float64]:
        """``(T, pairs)``: signed distance (coal) less the margin, per non-adjacent pair of links (m)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        pairs = self.pairs
        return self.geometry.pair_distances(q, pairs) - self.margin

    def describe(self) -> dict[str, Any]:
        return {"margin": self.margin, "pairs": list(self.labels),
                "rule": "sphere covers of the shapes (boxes exact against spheres), smooth minimum over each pair's "
                f"distances (lambda = {SMOOTHING_M} m); checked by coal signed distances"}


def check_rest_state(constraints: tuple, q: ArrayLike) -> None:
    """Refuse a rest position ``q`` that already breaks a constraint (named, with the worst label)."""
    q = np.asarray(q, dtype=float).reshape(1, -1)
    zeros = np.zeros_like(q)
    for constraint in constraints:
        margins = constraint.margins(q, zeros, zeros)[0]
        worst = int(np.argmin(margins))
        if margins[worst] < 0:
            what = "in collision" if constraint.name == "self_collision" else "beyond it"
            raise ConstraintError(f"--start is {what}: {constraint.name} {constraint.labels[worst]} margin "
                                  f"{margins[worst]:.4g} {constraint.unit}")


def constraints_from_options(robot: RobotModel, urdf: str | Path | None, *, torque_limits: bool = False,
                             floor: float | None = None, self_collision: bool = False,
                             collision_margin: float | None = None) -> tuple:
    """The constraints the command line's options ask for (``--torque-limits``, ``--floor Z``,
    ``--self-collision``, ``--collision-margin M``), read from the URDF ``urdf``.

    Raises
    ------
    ConstraintError
        A geometric option without a URDF, a link without collision geometry, no effort limits, a floor
        the base crosses, a collision margin without ``self_collision``.
    """
    if collision_margin is not None and not self_collision:
        raise ConstraintError("--collision-margin applies to --self-collision: give both")
    constraints: list[Any] = []
    if torque_limits:
        constraints.append(TorqueLimits.from_urdf(urdf, robot) if urdf is not None else TorqueLimits(robot))
    if (floor is not None or self_collision) and urdf is None:
        raise ConstraintError("--floor and --self-collision need the robot's collision geometry: give --urdf")
    if (floor is not None or self_collision) and is_mjcf(urdf):
        raise ConstraintError(f"--floor and --self-collision need the robot's collision geometry, read from a URDF: the "
                              f"geoms of the MJCF model {urdf} are not read (give the robot as --urdf)")
    geometry = read_collision_geometry(urdf, robot) if (floor is not None or self_collision) else None
    if floor is not None:
        constraints.append(Floor(robot, geometry, height=float(floor)))
    if self_collision:
        margin = DEFAULT_COLLISION_MARGIN if collision_margin is None else float(collision_margin)
        constraints.append(SelfCollision(robot, geometry, margin=margin))
    return tuple(constraints)
