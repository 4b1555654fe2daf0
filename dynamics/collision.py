"""Collision geometry of a URDF: primitives per link, their bounding spheres, and signed distances by coal.

The URDF's ``<collision>`` elements are read by Pinocchio (``buildGeomFromUrdf``, with coal/hpp-fcl
shapes). Each becomes a :class:`Primitive` placed in the frame of its parent joint (joint ``0``: the
base, i.e. links fixed to the root). Two representations are derived from it:

- **bounding spheres** for smooth distances inside an optimisation (:meth:`Primitive.spheres`):
  a sphere is itself; a capsule or cylinder of radius ``r`` and length ``L`` is covered by ``k``
  spheres centred on its axis segment at spacing ``s = L/(k-1) ≤ r``, each of radius
  ``sqrt(r² + (s/2)²)``; a mesh is bounded first by a capsule along its principal axis (the segment
  spanned by the vertices' projections, radius their largest distance from it). Every point of the
  shape lies in one of its spheres, so distances between spheres never exceed those of the shapes.
  A box is kept exact (:meth:`Primitive.corners`, and point–box distances).
- **exact signed distances** on the true shapes by Pinocchio's ``computeDistances`` (coal), used to
  check a trajectory independently of the bounding spheres (:class:`CollisionGeometry`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dynamics.errors import RobotDescriptionError
from dynamics.robot import RobotModel


@dataclass(frozen=True, eq=False)
class Primitive:
    """One collision shape: ``kind`` in ``sphere, capsule, cylinder, box, mesh``, on link ``link`` moved
    by joint ``joint`` (1-based; 0 the base), placed by the 4x4 ``placement`` in that joint's frame.

    ``radius``, ``half_length`` (along the local z axis) and ``half_extents`` (box) in metres;
    ``vertices`` ``(V, 3)`` of a mesh in its local frame.
    """

    name: str
    link: str
    joint: int
    kind: str
    placement: NDArray[np.float64]
    radius: float = 0.0
    half_length: float = 0.0
    half_extents: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    vertices: NDArray[np.float64] | None = None

    def spheres(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Centres ``(k, 3)`` in the joint frame and radii ``(k,)`` of spheres covering the shape
        (module docstring; a box: the spheres covering its bounding capsule along its longest edge)."""
        if self.kind == "sphere":
            local, radii = np.zeros((1, 3)), np.array([self.radius])
        else:
            axis, centre, half, radius = self.capsule()
            k = int(np.ceil(2 * half / radius - 1e-9)) + 1 if half > 0 else 1
            offsets = np.linspace(-half, half, k)
            spacing = 2 * half / (k - 1) if k > 1 else 0.0
            local = centre + offsets[:, None] * axis
            radii = np.full(k, np.sqrt(radius**2 + (spacing / 2) ** 2))
        return local @ self.placement[:3, :3].T + self.placement[:3, 3], radii

    def capsule(self) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:
        """``(axis, centre, half_length, radius)`` of a capsule bounding the shape, in its local frame."""
        z = np.array([0.0, 0.0, 1.0])
        if self.kind in ("capsule", "cylinder"):
            return z, np.zeros(3), self.half_length, self.radius
        if self.kind == "sphere":
            return z, np.zeros(3), 0.0, self.radius
        if self.kind == "box":
            longest = int(np.argmax(self.half_extents))
            axis = np.eye(3)[longest]
            others = np.delete(self.half_extents, longest)
            return axis, np.zeros(3), float(self.half_extents[longest]), float(np.linalg.norm(others))
        vertices = np.asarray(self.vertices, dtype=float)
        centre = vertices.mean(axis=0)
        _, _, directions = np.linalg.svd(vertices - centre, full_matrices=False)
        axis = directions[0]
        along = (vertices - centre) @ axis
        low, high = float(along.min()), float(along.max())
        middle = centre + (low + high) / 2 * axis
        half = (high - low) / 2
        offsets = np.clip((vertices - middle) @ axis, -half, half)
        radius = float(np.max(np.linalg.norm(vertices - middle - offsets[:, None] * axis, axis=1)))
        return axis, middle, half, max(radius, 1e-6)

    def corners(self) -> NDArray[np.float64]:
        """The 8 corners ``(8, 3)`` of a box in the joint frame."""
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
        local = signs * self.half_extents
        return local @ self.placement[:3, :3].T + self.placement[:3, 3]


@dataclass(frozen=True, eq=False)
class CollisionGeometry:
    """The collision primitives of a robot read from its URDF, with Pinocchio's models for exact checks.

    Attributes
    ----------
    primitives
        Every ``<collision>`` shape, in URDF order.
    link_names
        ``n + 1`` names: the base (joint 0) and the link each joint moves.
    """

    primitives: tuple[Primitive, ...]
    link_names: tuple[str, ...]
    model: Any = field(repr=False)
    geometry_model: Any = field(repr=False)
    _cache: dict = field(default_factory=dict, repr=False)

    def __getstate__(self) -> dict:
        """Pickled without the distance checker's Pinocchio data (rebuilt where unpickled)."""
        return {**self.__dict__, "_cache": {}}

    @property
    def n_joints(self) -> int:
        return len(self.link_names) - 1

    def on_joint(self, joint: int) -> list[int]:
        """Indices of the primitives moved by ``joint`` (0: the base)."""
        return [index for index, primitive in enumerate(self.primitives) if primitive.joint == joint]

    def links_without_geometry(self) -> list[str]:
        """Names of the moving links with no collision shape."""
        return [self.link_names[joint] for joint in range(1, self.n_joints + 1) if not self.on_joint(joint)]

    def non_adjacent_pairs(self) -> list[tuple[int, int]]:
        """Pairs of joints (``0`` the base) whose links are not adjacent in the chain (``j ≥ i + 2``)
        and both carry geometry."""
        carrying = [joint for joint in range(self.n_joints + 1) if self.on_joint(joint)]
        return [(i, j) for i in carrying for j in carrying if j >= i + 2]

    def placements(self, q: NDArray[np.float64]) -> list[Any]:
        """Pinocchio ``SE3`` placements of every primitive in the base frame at ``q``."""
        import pinocchio as pin

        data = self.model.createData()
        geometry_data = pin.GeometryData(self.geometry_model)
        pin.updateGeometryPlacements(self.model, data, self.geometry_model, geometry_data, np.asarray(q, float))
        return list(geometry_data.oMg)

    def lowest_points(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """Exact height (base-frame z) of the lowest point of each primitive at ``q`` (a mesh: its vertices)."""
        heights = []
        for primitive, placement in zip(self.primitives, self.placements(q)):
            rotation, origin = np.asarray(placement.rotation), np.asarray(placement.translation)
            axis_z = rotation[2, 2]
            if primitive.kind == "sphere":
                low = origin[2] - primitive.radius
            elif primitive.kind == "capsule":
                low = origin[2] - primitive.half_length * abs(axis_z) - primitive.radius
            elif primitive.kind == "cylinder":
                low = (origin[2] - primitive.half_length * abs(axis_z)
                       - primitive.radius * np.sqrt(max(0.0, 1 - axis_z**2)))
            elif primitive.kind == "box":
                low = origin[2] - float(np.abs(rotation[2]) @ primitive.half_extents)
            else:
                low = float(np.min(primitive.vertices @ rotation[2] + origin[2]))
            heights.append(low)
        return np.array(heights)

    def pair_distances(self, q: NDArray[np.float64], pairs: list[tuple[int, int]]) -> NDArray[np.float64]:
        """Smallest signed distance (m, negative: penetration) between the shapes of each pair of joints'
        links at ``q`` (one row per configuration when ``q`` is ``(T, n)``), by Pinocchio's
        ``computeDistances`` (coal): no cached collision guess."""
        import pinocchio as pin

        key = ("distances", tuple(pairs))
        if key not in self._cache:
            geometry_model = self.geometry_model.copy()
            geometry_model.removeAllCollisionPairs()
            members = []
            for i, j in pairs:
                members.append([])
                for a in self.on_joint(i):
                    for b in self.on_joint(j):
                        members[-1].append(len(geometry_model.collisionPairs))
                        geometry_model.addCollisionPair(pin.CollisionPair(a, b))
            self._cache[key] = (geometry_model, self.model.createData(), pin.GeometryData(geometry_model), members)
        geometry_model, data, geometry_data, members = self._cache[key]
        configurations = np.atleast_2d(np.asarray(q, dtype=float))
        result = np.empty((configurations.shape[0], len(pairs)))
        for row, sample in enumerate(configurations):
            pin.computeDistances(self.model, data, geometry_model, geometry_data, sample)
            distances = np.array([item.min_distance for item in geometry_data.distanceResults])
            result[row] = [distances[group].min() for group in members]
        return result if np.ndim(q) == 2 else result[0]


def read_collision_geometry(path: str | Path, robot: RobotModel) -> CollisionGeometry:
    """The ``<collision>`` shapes of the URDF ``path`` describing ``robot`` (:func:`dynamics.urdf.robot_from_urdf`).

    Meshes are looked up beside the file and in its parent folders (``package://NAME/...`` under a folder
    ``NAME``); their vertices are kept for the bounding capsule.

    Raises
    ------
    RobotDescriptionError
        When a mesh file cannot be found (named), or the file's chain is not ``robot``'s.
    """
    import pinocchio as pin

    path = Path(path)
    model = pin.buildModelFromUrdf(str(path))
    if model.njoints - 1 != robot.n_joints or list(model.names)[1:] != robot.joint_names:
        raise RobotDescriptionError(f"URDF {path} does not describe the robot {robot.name} (joints differ)")
    folders = [str(folder) for folder in [path.parent, *path.parent.parents]]
    try:
        geometry_model = pin.buildGeomFromUrdf(model, str(path), pin.COLLISION, package_dirs=folders)
    except ValueError as error:
        raise RobotDescriptionError(f"URDF {path}: collision geometry cannot be read: {error}") from None
    link_names = ["base"]
    for joint in range(1, model.njoints):
        children = [frame.name for frame in model.frames
                    if frame.parentJoint == joint and frame.type == pin.FrameType.BODY]
        link_names.append(children[0] if children else model.names[joint])
    roots = [frame.name for frame in model.frames if frame.parentJoint == 0 and frame.type == pin.FrameType.BODY]
    link_names[0] = roots[0] if roots else "base"
    primitives = []
    for item in geometry_model.geometryObjects:
        shape = item.geometry
        kind = type(shape).__name__.lower()
        common = dict(name=item.name, link=model.frames[item.parentFrame].name, joint=int(item.parentJoint),
                      placement=np.asarray(item.placement.homogeneous, dtype=float))
        if kind == "sphere":
            primitives.append(Primitive(kind="sphere", radius=float(shape.radius), **common))
        elif kind in ("capsule", "cylinder"):
            primitives.append(Primitive(kind=kind, radius=float(shape.radius), half_length=float(shape.halfLength),
                                        **common))
        elif kind == "box":
            primitives.append(Primitive(kind="box", half_extents=np.asarray(shape.halfSide, dtype=float), **common))
        else:
            vertices = _mesh_vertices(shape)
            if vertices is None:
                raise RobotDescriptionError(f"URDF {path}: collision shape {item.name!r} of link "
                                            f"{common['link']!r} is a {type(shape).__name__}, not supported")
            primitives.append(Primitive(kind="mesh", vertices=vertices, **common))
    return CollisionGeometry(tuple(primitives), tuple(link_names), model, geometry_model)


def _mesh_vertices(shape: Any) -> NDArray[np.float64] | None:
    """Vertices ``(V, 3)`` of a coal mesh or convex shape in its frame (``None`` for other shapes)."""
    for name in ("vertices", "points"):
        getter = getattr(shape, name, None)
        if getter is None:
            continue
        try:
            values = getter() if callable(getter) else getter
            array = np.asarray(values, dtype=float).reshape(-1, 3)
        except (TypeError, ValueError, RuntimeError):
            continue
        if array.size:
            return array
    return None
