"""The identified model as a file: everything needed to predict with it on another record.

``result.json`` (``oed identify``) and ``report.json`` (``oed diagnose``) carry the key ``model_file``::

    "model_file": {
        "format": "robot-oed identified model", "version": 1,
        "robot": {"name": "puma560[3]", "builtin": "puma560", "joints": 3,
                  "urdf": {"path": "/abs/arm.urdf", "sha256": "…", "text": "<robot …>" | null} | null,
                  "joint_names": ["torso_lift_joint", …], "locked_at": {"head_1_joint": 0.3}},  # when named
                  # "passive": ["elbow"]: the passive (unactuated) joints, their torque zero by physics (when any)
        "model": "internal", "channels": ["tau1", …], "joint_names": ["joint1", …],
        "effects": "viscous,coulomb:tanh",                   # the spec that rebuilds the model's columns
        "effect_values": [{"spec": "coulomb:tanh", "coefficients": {"fc1": 0.4, …}, "shape": {"vc1": 0.05}}],
        "shape": {"vc1": 0.05, …}, "shape_std": {…},        # fitted shape parameters (the delay apart)
        "smoothing": {"coulomb@2": 0.05},                    # Coulomb laws smoothed at rest (--rest smooth)
        "delay": {"value": 0.007, "std": 0.0002} | null,     # s; the motion moved to t − delay
        "transmission": {"matrix": …, "motors": …} | null,
        "base": {"names": […], "expressions": […]},
        "theta": […], "cov": [[…]],                           # base parameters and their covariance
        "channel_variance": {"tau1": …}, "weights": {"tau1": …}, "method": "wls",
        "recorded_variance": {"tau1": …},                    # training MSE against the channels as recorded
        "preprocessing": {method, frequency_hz | cutoff_hz, …},
        "rest": {"min_speed": 0.05, "rest": "drop"} | null, "max_gap": 0.05,
        "reported": {"validation_mse": {channel: value} | null},
        "consistent": {"links": [[m, mx, …, Izz], …], "effects": {"fv1": …},   # the consistent fit, when made
                       "theta": […], "cov": [[…]],                          # its base parameters
                       "validation_mse": {channel: value} | null} | null,
        "chosen": "wls" | "ols" | "consistent" | null,       # the model above (oed identify's choice; null: unnamed)
        "alternatives": {NAME: {"theta", "cov", "method", "channel_variance", "weights", "recorded_variance",
                                "validation_mse", "shape", "shape_std", "delay", "effect_values", "warnings"}},
        "payload": {"link": "joint6", "link_index": 6,                        # oed payload: a rigid body fixed
                    "parameters": [m, mx, …, Izz], "cov": [[…]]},            # to that link (absent: none)
        "joint_offsets": [0, -1.5708, …],                   # --joint-offsets: added to q as read (absent: none)
        "gravity": [0.0, 0.0, -9.81],                        # m/s², base frame: the gravity the model was fitted
                                                             # with (absent: an earlier release's file, the robot's)
        "subtracted": {"kind": "description_gravity", …},   # a load of the description the logged torques
                                                             # lack: predict subtracts it (absent: none)
        "joint_directions": {"signs": [1, -1, …],            # --joint-offsets' signs: q, dq, ddq and tau times
                             "torque_signs": [1, -1, …]},   # them as read, before the offsets (absent: none)
        "training_range": {"joints": {"joint1": {"q_min", "q_max", "dq_max"}, …},   # the samples the fit used
                           "n_samples": 9000, "tolerance": {…}}}   # (absent: an earlier release's file)

``theta``, ``cov`` and the keys beside them are the model the identification chose
(:mod:`estimation.consistent.model_selection`); the other candidates stay as named ``alternatives``, each
with what predicting with it needs (``oed predict --alternative NAME``).

The model's prediction along a motion is ``Y_b(q, q̇, q̈; s) θ`` with the shaped columns at the
fitted shapes ``s`` (:mod:`estimation.identification.shaped`), along the motion moved by the delay
(:mod:`estimation.preprocessing.delay`), plus, when the file carries a payload, ``Y_k(q, q̇, q̈) π``: the ten
standard-parameter columns of its link ``k`` times its parameters ``π`` (link frame, inertia about the link-frame
origin; :mod:`estimation.payload`).

:class:`ModelFile` is the parsed document (:func:`model_file_document` writes it for an in-memory fit,
:func:`summed_model_file_document` for one from sums, the streamed path);
:class:`estimation.identification.identified_model.IdentifiedModel` predicts with it.
"""

from __future__ import annotations

import hashlib
import json
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics.effects.shaped import shape_parameters
from dynamics.effects.specs import effect_spec
from dynamics.errors import RobotDescriptionError
from dynamics.mjcf import is_mjcf, mjcf_text
from dynamics.robot import RobotModel
from dynamics.robots import load_robot
from dynamics.transmission import JointDirections
from estimation.identification.fit import IdentificationResult
from estimation.identification.training_range import TrainingRange
from estimation.identification.subtracted_load import SubtractedLoad

__all__ = ["FORMAT", "MAX_EMBEDDED_URDF_BYTES", "MODEL_KEYS", "ModelFile", "ModelFileError", "RobotSource",
           "alternative_entry", "effect_entries", "model_file_document", "read_model_file", "summed_model_file_document",
           "with_model"]

FORMAT = "robot-oed identified model"
VERSION = 1
#: a URDF up to this size is embedded in the model file (a larger one by path and content hash only)
MAX_EMBEDDED_URDF_BYTES = 1_000_000
#: the name of the delay among a result's shape values
DELAY_NAME = "delay"


class ModelFileError(ValueError):
    """A file that is not a model file, or one whose robot cannot be found again."""


@dataclass(frozen=True)
class RobotSource:
    """Where the robot came from: a built-in name, or a URDF or MuJoCo MJCF file (path, content hash and, if small,
    text; an MJCF's with its ``<include>`` files in place), read again by :func:`dynamics.robots.load_robot`."""

    name: str
    builtin: str | None = None
    joints: int | None = None
    urdf_path: str | None = None
    urdf_sha256: str | None = None
    urdf_text: str | None = None
    joint_names: tuple[str, ...] | None = None
    locked_at: Mapping[str, float] | None = None
    passive: tuple[str, ...] = ()  # the passive (unactuated) joints' names (their torque zero by physics)

    @classmethod
    def from_description(cls, robot: RobotModel, *, builtin: str | None, urdf: str | Path | None,
                         joints: int | None, joint_names: Sequence[str] | None = None,
                         locked_at: Mapping[str, float] | None = None) -> RobotSource:
        """The source of ``robot``, read from ``builtin`` (a name of :data:`dynamics.robots.BUILT_IN_ROBOTS`) or ``urdf``
        (with the logged ``joint_names`` and the ``locked_at`` positions of the others, when given)."""
        passive = tuple(robot.passive_joints)
        if urdf is None:
            return cls(robot.name, builtin, joints, passive=passive)
        path = Path(urdf).expanduser().resolve()
        data = path.read_bytes()
        text = data.decode("utf-8", errors="replace") if len(data) <= MAX_EMBEDDED_URDF_BYTES else None
        if text is not None and is_mjcf(path):  # an MJCF model: its <include> files in place, read alone again
            text = mjcf_text(path)
            text = text if len(text.encode()) <= MAX_EMBEDDED_URDF_BYTES else None
        return cls(robot.name, None, joints, str(path), hashlib.sha256(data).hexdigest(), text,
                   None if joint_names is None else tuple(joint_names),
                   None if not locked_at else {name: float(value) for name, value in locked_at.items()}, passive)

    def _load_urdf(self, path: Path) -> RobotModel:
        return load_robot(urdf=path, joints=self.joints, joint_names=self.joint_names, locked_at=self.locked_at,
                          passive=self.passive)

    def load(self) -> RobotModel:
        """The robot again: the embedded URDF text, else the file at ``urdf_path`` if its hash matches,
        else the built-in robot."""
        if self.urdf_sha256 is None:
            if self.builtin is None:
                raise ModelFileError(f"the model file names robot {self.name!r} without a built-in name or a URDF")
            return load_robot(self.builtin, joints=self.joints, passive=self.passive)
        if self.urdf_text is not None:
            with tempfile.TemporaryDirectory() as folder:
                path = Path(folder) / "robot.urdf"
                path.write_text(self.urdf_text)
                return self._load_urdf(path)
        path = Path(self.urdf_path or "")
        if not path.is_file():
            raise ModelFileError(f"the model's URDF {self.urdf_path} is not there any more (and was too large to "
                                 "embed): put it back at that path")
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        if digest != self.urdf_sha256:
            raise ModelFileError(f"the URDF {path} changed since the identification (sha256 {digest[:12]}…, the model "
                                 f"file says {self.urdf_sha256[:12]}…): the model's base parameters belong to the old one")
        return self._load_urdf(path)

    def to_dict(self) -> dict[str, Any]:
        urdf = None if self.urdf_sha256 is None else {"path": self.urdf_path, "sha256": self.urdf_sha256,
                                                       "text": self.urdf_text}
        document = {"name": self.name, "builtin": self.builtin, "joints": self.joints, "urdf": urdf}
        if self.joint_names is not None:
            document["joint_names"] = list(self.joint_names)
        if self.locked_at:
            document["locked_at"] = dict(self.locked_at)
        if self.passive:
            document["passive"] = list(self.passive)
        return document

    @classmethod
    def from_dict(cls, document: Mapping[str, Any]) -> RobotSource:
        urdf = document.get("urdf") or {}
        names = document.get("joint_names")
        return cls(str(document["name"]), document.get("builtin"), document.get("joints"), urdf.get("path"),
                   urdf.get("sha256"), urdf.get("text"), None if names is None else tuple(names),
                   document.get("locked_at") or None, tuple(str(name) for name in document.get("passive") or ()))


@dataclass(frozen=True)
class ModelFile:
    """The parsed ``model_file`` document (module docstring)."""

    robot: RobotSource
    model: str
    channels: tuple[str, ...]
    joint_names: tuple[str, ...]
    effects: str
    names: tuple[str, ...]
    expressions: tuple[str, ...]
    theta: NDArray[np.float64]
    cov: NDArray[np.float64]
    channel_variance: NDArray[np.float64]
    weights: NDArray[np.float64]
    method: str
    shape: Mapping[str, float] = field(default_factory=dict)
    shape_std: Mapping[str, float] = field(default_factory=dict)
    smoothing: Mapping[str, float] = field(default_factory=dict)
    delay: float | None = None
    delay_std: float | None = None
    transmission: Mapping[str, Any] | None = None
    preprocessing: Mapping[str, Any] | None = None
    rest: Mapping[str, Any] | None = None
    max_gap: float | None = None
    reported_validation_mse: Mapping[str, float] | None = None
    effect_values: tuple[Mapping[str, Any], ...] = ()
    consistent_links: NDArray[np.float64] | None = None
    consistent_effects: Mapping[str, float] | None = None
    recorded_variance: NDArray[np.float64] | None = None
    consistent_theta: NDArray[np.float64] | None = None
    consistent_cov: NDArray[np.float64] | None = None
    consistent_validation_mse: Mapping[str, float] | None = None
    payload: Mapping[str, Any] | None = None
    chosen: str | None = None
    alternatives: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    joint_offsets: tuple[float, ...] | None = None
    joint_directions: JointDirections | None = None
    #: ``{channels: {tau1: {value, std}, …}, scale}``: each channel's recorded torque is its gain times the model's
    #: (:mod:`estimation.consistent.torque_gains`); ``None``: none
    torque_gains: Mapping[str, Any] | None = None
    #: each joint's position range and largest speed on the samples the fit used
    #: (:mod:`estimation.identification.training_range`); ``None``: a file of an earlier release
    training_range: TrainingRange | None = None
    #: the gravity vector in the base frame (m/s²) the model was fitted with: the description's, or the one the
    #: mount check found when that candidate won on the validation record; ``None``: a file of an earlier release
    #: (the robot description's gravity)
    gravity: NDArray[np.float64] | None = None
    #: a known load of the description the logged torques have subtracted
    #: (:class:`~estimation.identification.subtracted_load.SubtractedLoad`: ``oed predict`` subtracts it from the
    #: model's torques, as the log did); ``None``: nothing subtracted (and a file of an earlier release)
    subtracted: SubtractedLoad | None = None

    @property
    def band_variance(self) -> NDArray[np.float64]:
        """The channels' noise variance of the prediction band: the training MSE against the channels
        as recorded (the fit's residual variance is against filtered or averaged ones when the
        preprocessing made them)."""
        return self.channel_variance if self.recorded_variance is None else self.recorded_variance

    def to_dict(self) -> dict[str, Any]:
        """The ``model_file`` document (module docstring)."""
        channels = list(self.channels)
        document = {
            "format": FORMAT, "version": VERSION,
            "robot": self.robot.to_dict(), "model": self.model, "channels": channels,
            "joint_names": list(self.joint_names), "effects": self.effects,
            "effect_values": [dict(entry) for entry in self.effect_values],
            "shape": dict(self.shape), "shape_std": dict(self.shape_std), "smoothing": dict(self.smoothing),
            "delay": None if self.delay is None else {"value": self.delay, "std": self.delay_std, "unit": "s"},
            "transmission": None if self.transmission is None else dict(self.transmission),
            "base": {"names": list(self.names), "expressions": list(self.expressions)},
            "theta": self.theta.tolist(), "cov": self.cov.tolist(),
            "channel_variance": dict(zip(channels, self.channel_variance.tolist())),
            "weights": dict(zip(channels, self.weights.tolist())), "method": self.method,
            "recorded_variance": None if self.recorded_variance is None
            else dict(zip(channels, self.recorded_variance.tolist())),
            "preprocessing": None if self.preprocessing is None else dict(self.preprocessing),
            "rest": None if self.rest is None else dict(self.rest), "max_gap": self.max_gap,
            "reported": {"validation_mse": None if self.reported_validation_mse is None
                         else dict(self.reported_validation_mse)},
            "consistent": None if self.consistent_links is None else {
                "links": self.consistent_links.tolist(), "effects": dict(self.consistent_effects or {}),
                "theta": None if self.consistent_theta is None else self.consistent_theta.tolist(),
                "cov": None if self.consistent_cov is None else self.consistent_cov.tolist(),
                "validation_mse": None if self.consistent_validation_mse is None
                else dict(self.consistent_validation_mse)},
            "chosen": self.chosen,
            "alternatives": {name: dict(entry) for name, entry in self.alternatives.items()},
        }
        if self.payload is not None:  # written only when there is one: files without it stay as they were
            document["payload"] = dict(self.payload)
        if self.joint_offsets is not None:  # --joint-offsets: added to the joint positions of every record read
            document["joint_offsets"] = list(self.joint_offsets)
        if self.joint_directions is not None:  # --joint-offsets' signs: applied to every record read
            document["joint_directions"] = self.joint_directions.to_dict()
        if self.torque_gains is not None:  # the recorded torques over the model's, per channel
            document["torque_gains"] = dict(self.torque_gains)
        if self.training_range is not None:  # the samples the fit used: where the model does not extrapolate
            document["training_range"] = self.training_range.to_dict()
        if self.gravity is not None:  # the gravity the model was fitted with, in the base frame
            document["gravity"] = [float(value) for value in self.gravity]
        if self.subtracted is not None:  # the load the log lacks: the model's torques less it are the log's
            document["subtracted"] = self.subtracted.to_dict()
        return document

    def channel_gains(self) -> NDArray[np.float64]:
        """Each channel's gain on the recorded torque (``torque_gains``; ``1`` without one)."""
        held = (self.torque_gains or {}).get("channels") or {}
        return np.array([float(held[channel]["value"]) if channel in held else 1.0 for channel in self.channels])

    @classmethod
    def from_dict(cls, document: Mapping[str, Any]) -> ModelFile:
        """Parse a ``model_file`` document; :class:`ModelFileError` names what is missing."""
        if document.get("format") != FORMAT:
            raise ModelFileError(f"not a model file (format {document.get('format')!r}, expected {FORMAT!r})")
        if int(document.get("version", 0)) > VERSION:
            raise ModelFileError(f"model file version {document['version']} is newer than this program reads ({VERSION})")
        try:
            channels = tuple(document["channels"])
            delay = document.get("delay")
            consistent = document.get("consistent")
            return cls(
                robot=RobotSource.from_dict(document["robot"]), model=str(document["model"]), channels=channels,
                joint_names=tuple(document["joint_names"]), effects=str(document["effects"]),
                names=tuple(document["base"]["names"]), expressions=tuple(document["base"]["expressions"]),
                theta=np.asarray(document["theta"], dtype=float),
                cov=np.asarray(document["cov"], dtype=float).reshape(len(document["theta"]), -1),
                channel_variance=np.array([document["channel_variance"][c] for c in channels], dtype=float),
                weights=np.array([document["weights"][c] for c in channels], dtype=float),
                method=str(document.get("method", "wls")),
                shape=dict(document.get("shape") or {}), shape_std=dict(document.get("shape_std") or {}),
                smoothing=dict(document.get("smoothing") or {}),
                delay=None if delay is None else float(delay["value"]),
                delay_std=None if delay is None or delay.get("std") is None else float(delay["std"]),
                transmission=document.get("transmission"), preprocessing=document.get("preprocessing"),
                rest=document.get("rest"), max_gap=document.get("max_gap"),
                reported_validation_mse=(document.get("reported") or {}).get("validation_mse"),
                effect_values=tuple(document.get("effect_values") or ()),
                consistent_links=None if consistent is None else np.asarray(consistent["links"], dtype=float),
                consistent_effects=None if consistent is None else dict(consistent.get("effects") or {}),
                consistent_theta=None if consistent is None or consistent.get("theta") is None
                else np.asarray(consistent["theta"], dtype=float),
                consistent_cov=None if consistent is None or consistent.get("cov") is None
                else np.asarray(consistent["cov"], dtype=float).reshape(len(consistent["theta"]), -1),
                consistent_validation_mse=None if consistent is None else consistent.get("validation_mse"),
                recorded_variance=None if document.get("recorded_variance") is None
                else np.array([document["recorded_variance"][c] for c in channels], dtype=float),
                payload=_payload(document.get("payload")),
                chosen=document.get("chosen"), alternatives=dict(document.get("alternatives") or {}),
                joint_offsets=_joint_offsets(document.get("joint_offsets"), len(document["joint_names"])),
                joint_directions=_joint_directions(document.get("joint_directions"), len(document["joint_names"])),
                torque_gains=_torque_gains(document.get("torque_gains"), channels),
                training_range=_training_range(document.get("training_range"), document["joint_names"]),
                gravity=_gravity(document.get("gravity")),
                subtracted=_subtracted(document.get("subtracted")),
            )
        except (KeyError, TypeError) as error:
            raise ModelFileError(f"the model file lacks or garbles {error}") from None


def _subtracted(values: Any) -> SubtractedLoad | None:
    """The ``subtracted`` entry, checked: a load of a known kind (absent or ``null``: nothing subtracted)."""
    if values is None:
        return None
    try:
        return SubtractedLoad.from_dict(values)
    except (TypeError, ValueError) as error:
        raise ModelFileError(f"the model file's subtracted load is garbled: {error}") from None


def _gravity(values: Any) -> NDArray[np.float64] | None:
    """The ``gravity`` entry, checked: three finite numbers, m/s² in the base frame (absent: ``None``)."""
    if values is None:
        return None
    try:
        gravity = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        gravity = np.empty(0)
    if gravity.shape != (3,) or not np.all(np.isfinite(gravity)):
        raise ModelFileError(f"gravity must be three finite numbers (m/s² in the base frame), got {values!r}")
    return gravity


def _training_range(values: Any, joint_names: Sequence[str]) -> TrainingRange | None:
    """The ``training_range`` entry, checked: a range for each of the model's joints (absent: ``None``)."""
    if values is None:
        return None
    try:
        ranges = TrainingRange.from_dict(values)
    except ValueError as error:
        raise ModelFileError(str(error)) from None
    if list(ranges.joint_names) != list(joint_names):
        raise ModelFileError(f"the training range's joints {list(ranges.joint_names)} are not the model's "
                             f"{list(joint_names)}")
    return ranges


def _torque_gains(values: Any, channels: tuple[str, ...]) -> Mapping[str, Any] | None:
    """The ``torque_gains`` entry, checked: a positive finite gain for channels of the model."""
    if values is None:
        return None
    held = values.get("channels") if isinstance(values, Mapping) else None
    if not isinstance(held, Mapping) or not set(held) <= set(channels):
        raise ModelFileError(f"torque_gains must hold gains of the channels {list(channels)}, got {values!r}")
    for channel, entry in held.items():
        value = entry.get("value") if isinstance(entry, Mapping) else None
        if not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0.0:
            raise ModelFileError(f"torque_gains of {channel} must be a positive number, got {entry!r}")
    return dict(values)


def _joint_offsets(values: Any, n_joints: int) -> tuple[float, ...] | None:
    """The ``joint_offsets`` entry, checked: one finite number a joint."""
    if values is None:
        return None
    try:
        offsets = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ModelFileError(f"joint_offsets must be {n_joints} numbers, got {values!r}") from None
    if offsets.shape != (n_joints,) or not np.all(np.isfinite(offsets)):
        raise ModelFileError(f"joint_offsets must be {n_joints} finite numbers, got {values!r}")
    return tuple(float(value) for value in offsets)


def _joint_directions(values: Any, n_joints: int) -> JointDirections | None:
    """The ``joint_directions`` entry, checked: ``signs`` and ``torque_signs``, one +1 or -1 a joint."""
    if values is None:
        return None
    try:
        directions = JointDirections(*(tuple(float(value) for value in values[key])
                                       for key in ("signs", "torque_signs")))
    except (TypeError, ValueError, KeyError):
        raise ModelFileError(f"joint_directions must hold signs and torque_signs, {n_joints} times +1 or -1 each, "
                             f"got {values!r}") from None
    if len(directions.signs) != n_joints:
        raise ModelFileError(f"joint_directions must hold {n_joints} signs, got {values!r}")
    return directions


def _payload(document: Any) -> dict[str, Any] | None:
    """The ``payload`` entry, checked: a link and ten parameters with their ``10 x 10`` covariance."""
    if document is None:
        return None
    if not isinstance(document, Mapping):
        raise ModelFileError("the model file's payload is not an object")
    try:
        parameters = np.asarray(document["parameters"], dtype=float).reshape(-1)
        cov = np.asarray(document["cov"], dtype=float)
        index = int(document["link_index"])
    except (KeyError, TypeError, ValueError) as error:
        raise ModelFileError(f"the model file's payload lacks or garbles {error}") from None
    if parameters.shape != (10,) or cov.shape != (10, 10) or not np.all(np.isfinite(parameters)):
        raise ModelFileError("the model file's payload must hold 10 finite parameters and a 10 x 10 covariance")
    return {**dict(document), "link_index": index, "parameters": parameters.tolist(), "cov": cov.tolist()}


def _effect_values(result: IdentificationResult) -> tuple[dict[str, Any], ...]:
    """Each effect's spec, its coefficients that are base parameters of their own, and its shape."""
    shapes = {value.name: float(value.value) for value in result.shapes if value.name != DELAY_NAME}
    estimate = result.estimate
    return effect_entries(result.model, estimate.names, estimate.expressions, estimate.values, shapes)


def effect_entries(model: Any, names: Sequence[str], expressions: Sequence[str], values: ArrayLike,
                   shapes: Mapping[str, float]) -> tuple[dict[str, Any], ...]:
    """The ``effect_values`` entries of a fit of ``model``: base parameters ``names`` (their
    ``expressions`` and ``values``) and fitted ``shapes`` by name."""
    values = dict(zip(names, map(float, np.asarray(values, dtype=float))))
    expressions = dict(zip(names, expressions))
    entries = []
    for effect in model.effects:
        parameter_names = list(effect.parameter_names(model.robot))
        shape_names = [parameter.name for parameter in shape_parameters(effect, model.robot)]
        entries.append({
            "spec": effect_spec(effect),
            "coefficients": {name: values[name] for name in parameter_names
                             if name in values and expressions[name].strip() == name},
            "shape": {name: float(shapes[name]) for name in shape_names if name in shapes},
        })
    return tuple(entries)


def summed_model_file_document(model: Any, estimate: Any, *, robot: RobotSource, preprocessing: Mapping[str, Any],
                               shape: Mapping[str, float] | None = None,
                               recorded_mse: Mapping[str, float] | None = None,
                               validation_mse: Mapping[str, float] | None = None, consistent: Any = None,
                               consistent_validation_mse: Mapping[str, float] | None = None) -> dict[str, Any]:
    """The ``model_file`` document of an estimate from sums (the streamed path,
    :class:`estimation.estimators.summed_least_squares.SummedEstimate`) of ``model``.

    ``shape``: the fixed shapes of its shaped laws (and the adopted delay, :data:`DELAY_NAME`: the file's ``delay``,
    its standard deviation not held); ``recorded_mse``: the training MSE against the channels
    as recorded (the prediction band's noise; ``None``: the fit's residual variance serves);
    ``validation_mse``: the validation MSE against the channels as recorded, as ``oed predict`` measures it;
    ``consistent``: the :class:`estimation.consistent.least_squares.ConsistentEstimate` of a physically consistent
    refit from the sums, or ``None``, with its validation MSE (as :func:`model_file_document`'s).
    """
    names = tuple(model.base.names)
    if sorted(estimate.names) != sorted(names):
        raise ModelFileError("the estimate's parameters are not the base parameters of the model rebuilt from its "
                             f"effects ({list(estimate.names)[:5]}… against {list(names)[:5]}…)")
    order = [list(estimate.names).index(name) for name in names]  # the model's order
    theta = np.asarray(estimate.values, dtype=float)[order]
    channels = tuple(model.channels)
    shape = {} if shape is None else {name: float(value) for name, value in shape.items()}
    delay = shape.pop(DELAY_NAME, None)  # a diagnosis's adopted delay among its shapes: the file's ``delay``
    document = ModelFile(
        robot=robot, model=model.kind.value, channels=channels, joint_names=tuple(model.robot.joint_names),
        effects=",".join(effect_spec(effect) for effect in model.effects) or "none",
        names=names, expressions=tuple(model.base.expressions),
        theta=theta, cov=np.asarray(estimate.cov, dtype=float)[np.ix_(order, order)],
        channel_variance=np.asarray(estimate.channel_variance, dtype=float),
        weights=np.broadcast_to(np.asarray(estimate.weights, dtype=float), (len(channels),)).copy(),
        method=estimate.method, shape=shape, preprocessing=dict(preprocessing), delay=delay,
        reported_validation_mse=None if validation_mse is None else dict(validation_mse),
        effect_values=effect_entries(model, names, model.base.expressions, theta, shape),
        recorded_variance=None if recorded_mse is None else np.array([recorded_mse[c] for c in channels], dtype=float),
        consistent_links=None if consistent is None else np.asarray(consistent.link_parameters(), dtype=float),
        consistent_effects=None if consistent is None else dict(consistent.effect_values()),
        consistent_theta=None if consistent is None else np.asarray(consistent.values, dtype=float),
        consistent_cov=None if consistent is None else np.asarray(consistent.cov, dtype=float),
        consistent_validation_mse=None if consistent_validation_mse is None else dict(consistent_validation_mse),
        gravity=np.asarray(model.robot.gravity, dtype=float),
    )
    return document.to_dict()


def model_file_document(result: IdentificationResult, *, robot: RobotSource, preprocessing: Mapping[str, Any] | None,
                        transmission: Any = None, rest: Mapping[str, Any] | None = None, max_gap: float | None = None,
                        consistent: Any = None, consistent_validation_mse: Mapping[str, float] | None = None
                        ) -> dict[str, Any]:
    """The ``model_file`` document of ``result`` (module docstring).

    ``transmission``: a :class:`dynamics.transmission.Transmission` or ``None``; ``rest``: ``{min_speed,
    rest}`` when rows at rest were dropped or Coulomb laws smoothed; ``consistent``: the
    :class:`estimation.consistent.least_squares.ConsistentEstimate` of a physically consistent refit, or
    ``None``, with its validation MSE.
    """
    model, estimate = result.model, result.estimate
    shapes = [value for value in result.shapes if value.name != DELAY_NAME]
    smoothing = {effect_spec(effect): float(effect.smoothing) for effect in model.effects
                 if getattr(effect, "smoothing", None) is not None and not hasattr(effect, "spec")}
    weights = estimate.weights if estimate.weights is not None else np.ones(model.n_channels)
    document = ModelFile(
        robot=robot, model=model.kind.value, channels=tuple(model.channels), joint_names=tuple(model.robot.joint_names),
        effects=",".join(effect_spec(effect) for effect in model.effects) or "none",
        names=tuple(estimate.names), expressions=tuple(estimate.expressions),
        theta=np.asarray(estimate.values, dtype=float), cov=np.asarray(estimate.cov, dtype=float),
        channel_variance=np.asarray(estimate.channel_variance, dtype=float),
        weights=np.broadcast_to(np.asarray(weights, dtype=float), (model.n_channels,)).copy(),
        method=estimate.method,
        shape={value.name: float(value.value) for value in shapes},
        shape_std={value.name: float(value.std) for value in shapes}, smoothing=smoothing,
        delay=None if result.delay is None else float(result.delay.value),
        delay_std=None if result.delay is None else float(result.delay.std),
        transmission=None if transmission is None else transmission.to_dict(),
        preprocessing=None if preprocessing is None else dict(preprocessing),
        rest=None if rest is None else dict(rest), max_gap=max_gap,
        reported_validation_mse=None if result.validation is None else dict(result.validation.mse),
        effect_values=_effect_values(result),
        consistent_links=None if consistent is None else np.asarray(consistent.link_parameters(), dtype=float),
        consistent_effects=None if consistent is None else dict(consistent.effect_values()),
        consistent_theta=None if consistent is None else np.asarray(consistent.values, dtype=float),
        consistent_cov=None if consistent is None else np.asarray(consistent.cov, dtype=float),
        consistent_validation_mse=None if consistent_validation_mse is None else dict(consistent_validation_mse),
        recorded_variance=np.array([result.train.mse[channel] for channel in model.channels]),
        gravity=np.asarray(model.robot.gravity, dtype=float),
    )
    return document.to_dict()


#: the keys of a model file that make one model: what an alternative holds
MODEL_KEYS = ("theta", "cov", "method", "channel_variance", "weights", "recorded_variance", "shape", "shape_std",
              "delay", "effect_values")


def alternative_entry(document: Mapping[str, Any]) -> dict[str, Any]:
    """The ``alternatives`` entry of the model of a ``model_file`` document: its :data:`MODEL_KEYS` and
    ``validation_mse`` (the validation MSE reported for it)."""
    return {**{key: document.get(key) for key in MODEL_KEYS},
            "validation_mse": (document.get("reported") or {}).get("validation_mse")}


def with_model(document: Mapping[str, Any], entry: Mapping[str, Any]) -> dict[str, Any]:
    """``document`` with its model (:data:`MODEL_KEYS`, the reported validation MSE) replaced by ``entry``'s."""
    replaced = dict(document)
    replaced.update({key: entry.get(key) for key in MODEL_KEYS})
    replaced["reported"] = {"validation_mse": entry.get("validation_mse")}
    return replaced


def read_model_file(path: str | Path) -> ModelFile:
    """The model file in ``path``: a ``result.json``/``report.json`` (its key ``model_file``) or the
    ``model_file`` document itself."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"model file not found: {path}")
    try:
        document = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ModelFileError(f"{path} is not JSON: {error}") from None
    if not isinstance(document, dict):
        raise ModelFileError(f"{path} holds no JSON object")
    if "model_file" in document:
        if document["model_file"] is None:
            raise ModelFileError(f"{path} holds no model")
        document = document["model_file"]
    elif document.get("format") != FORMAT:
        raise ModelFileError(f"{path} holds no model: it has no key 'model_file' (written by `oed identify` and "
                             "`oed diagnose` from this release on; run them again)")
    try:
        return ModelFile.from_dict(document)
    except RobotDescriptionError as error:
        raise ModelFileError(f"{path}: {error}") from None
    except ModelFileError as error:
        raise ModelFileError(f"{path}: {error}") from None
