"""Has the robot's load or mount changed since the training? A check of the record ``oed predict`` is given.

A model identified on one day predicts a record of another: a gripper may hold a part the training never saw, a
mobile base may stand off level. The model cannot know it, and the error alone does not say it. The check tests
the residual of the model's prediction ``r = y − ŷ`` on the record against two small, physically named families
of what may have changed, each linear (or nearly) in a few parameters ``β``:

- **a payload on the last link**: ``Y_k β``, ``Y_k`` the ten standard-parameter columns of the link (the
  Newton–Euler regressor, the columns ``oed payload`` fits, :mod:`estimation.payload.fit`), ``β`` a rigid body's
  mass, first moments and inertia about the link's frame (negative: a load taken off);
- **gravity turned** (the base off level, or mounted otherwise): with ``ĝ`` the model's gravity direction and
  ``e_1, e_2`` two directions square to it, gravity ``|g| (u_0 ĝ + u_1 e_1 + u_2 e_2)``, ``u_0 = √(1 − u_1² − u_2²)``
  (:mod:`estimation.identification.mount`), so ``Δτ = (u_0 − 1) G_0 + u_1 G_1 + u_2 G_2``, ``G_a(q)`` the gravity
  load along each direction of the model's bodies: its base parameters completed by the description's for what the
  training left undetermined, ``θ_s = θ_nom + K⁺ (θ_b − K θ_nom)`` (``θ_b = K θ_s``). Two angles, fitted by
  Gauss–Newton from level. The description's share ``(I − K⁺K) θ_nom`` is given the relative error the description
  shows where the training saw it (``‖θ_b − K θ_nom‖ / ‖K θ_nom‖`` over the bodies' base parameters), propagated
  into the angles' covariance: on a simulated PUMA whose bodies are the description's ±20 %, the angle of a 2° tilt
  is 1.84° with the description's share, 1.98° with the true bodies.

Each family is fitted by weighted least squares (each channel weighted by its noise floor on this record) and said
only when all of these hold:

1. **its coefficients are far from zero for the noise of the record**: the Wald test ``W = βᵀ C⁻¹ β`` with ``C`` the
   prewhitened Newey–West covariance (:func:`estimation.uncertainty.covariance.hac_covariance`: residuals correlated
   in time) plus the model's own uncertainty propagated through the fit (``S Σ_θ Sᵀ``, as ``oed payload``) and,
   for gravity, the description's share of the bodies (above), at
   ``p <`` :data:`ALPHA` over the families (Bonferroni), the statistic the diagnosis adopts effects with
   (:mod:`estimation.diagnosis.rules.robust_test`);
2. **it explains most of the error on some channel, on samples its fit did not see**: the record's two halves
   cross-fitted (each half predicted with the coefficients fitted on the other), a channel's error at most
   :data:`MARK` of the model's and at least :data:`MIN_FLOORS` noise floors less;
3. **no channel is made worse** (cross-fitted, more than :data:`WORSE_LIMIT` times the model's error and
   :data:`WORSE_FLOORS` noise floors more): a load or
   a mount is the whole robot's, and a family that serves one channel at another's expense is fitting something
   else.

On real robots' test records the Wald test alone often marks (the TX40's: p = 2e-10 for the payload, 2e-12 for
gravity, neither lowering any channel's cross-fitted error by 6 %) and the payload's ten columns absorb some of the
model's own errors (the KUKA LWR4+'s identify model: tau2 and tau4 cross-fitted to 0.29 and 0.27 of the model's
error, 4 noise floors less, p = 5e-5): the second condition is what keeps them silent. The simulated changes it says
(a 2 kg payload: tau2, tau3 to 0.03 and 0.01 of the error, 600-3000 floors less; a 2° tilt: tau1 to 0.04, 33 floors
less) stand well inside it. When
both families are said, the one with the lower cross-fitted error is named first. Nothing in the prediction
changes: the error the model would have with the change is reported beside it, labelled as fitted on this record
(not a held-out figure).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import casadi
import numpy as np
from numpy.typing import NDArray

from dynamics.channels import is_joint_torque
from dynamics.measurements import Measurements
from dynamics.codegen.compiled import SampleEvaluator
from dynamics.models import ModelKind
from dynamics.newton_euler import rigid_body_regressors
from estimation.data.segments import segment_slices
from estimation.uncertainty.wald import wald_test
from estimation.identification.mount import mount_rpy
from estimation.preprocessing.delay import delayed
from estimation.uncertainty.covariance import hac_covariance

if TYPE_CHECKING:
    from estimation.identification.identified_model import IdentifiedModel, Prediction

__all__ = ["ALPHA", "FITTED_LABEL", "MARK", "MIN_FLOORS", "WORSE_FLOORS", "WORSE_LIMIT", "FamilyFit", "RecordChanges",
           "check_record_changes", "rest_regressors"]

#: the family-wise level of the test over the families (Bonferroni)
ALPHA = 1e-3
#: a channel's cross-fitted error at most this share of the model's: the change explains most of it
MARK = 0.25
#: and at least this many noise floors less on that channel: more than the noise could give
MIN_FLOORS = 10.0
#: no channel's cross-fitted error more than this many times the model's and :data:`WORSE_FLOORS` noise floors more
WORSE_LIMIT = 1.05
#: (a channel at its floor may lose a floor or so to the cross-fitting: half the record's coefficients on the other
#: half's motion)
WORSE_FLOORS = 2.0
#: at most this many evenly spaced samples enter the fits (the error with the change is taken on every sample)
MAX_SAMPLES = 6000
#: samples per block when the error with the change is taken on every sample (the columns' memory)
CHUNK = 4000
#: eigenvalues of the scaled normal matrix below this fraction of the largest: directions no sample determines
STRUCTURAL_TOLERANCE = 1e-10
FITTED_LABEL = "fitted on this record (not a held-out figure): the model's error were the change in it"
PAYLOAD_NAMES = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz")


@dataclass(frozen=True)
class FamilyFit:
    """One family fitted to the residual of a record.

    Attributes
    ----------
    name
        ``payload`` or ``gravity``.
    coefficients, cov
        The fitted parameters ``β`` (the payload's ten; the gravity's ``u_1, u_2``) and their covariance (the
        record's noise, HAC, plus the model's own uncertainty).
    p_value, statistic
        The Wald test of ``β = 0`` (module docstring).
    model_mse, cross_fitted_mse, fitted_mse
        Each channel's MSE on the record: the model's, with the change cross-fitted (each half predicted by the
        other's fit; on the fit's samples), and with the change fitted on the whole record (every sample).
    floor
        Each channel's noise floor (MSE) on this record, the yardstick of the effect size.
    said
        Whether the check says the change (module docstring).
    """

    name: str
    coefficients: NDArray[np.float64]
    cov: NDArray[np.float64]
    statistic: float
    p_value: float
    model_mse: dict[str, float]
    cross_fitted_mse: dict[str, float]
    fitted_mse: dict[str, float]
    floor: dict[str, float]
    said: bool
    details: dict[str, Any] = field(default_factory=dict)

    @property
    def cross_fitted_ratio(self) -> dict[str, float]:
        """Each channel's cross-fitted error over the model's."""
        return {channel: value / self.model_mse[channel] if self.model_mse[channel] > 0 else 1.0
                for channel, value in self.cross_fitted_mse.items()}

    def words(self) -> str:
        """The change in words with its estimate and standard deviation."""
        return str(self.details["words"])

    def to_dict(self) -> dict[str, Any]:
        return {"change": self.name, "said": self.said, "words": self.words(),
                **{key: value for key, value in self.details.items() if key != "words"},
                "p_value": self.p_value, "wald_statistic": self.statistic,
                "model_mse": self.model_mse, "cross_fitted_mse": self.cross_fitted_mse,
                "cross_fitted_ratio": self.cross_fitted_ratio,
                "mse_with_change": self.fitted_mse, "mse_with_change_label": FITTED_LABEL,
                "noise_floor_mse": self.floor}


@dataclass(frozen=True)
class RecordChanges:
    """What the check found on a record: every family it tested, and those it says (best first)."""

    families: tuple[FamilyFit, ...]
    floor_source: str

    @property
    def said(self) -> tuple[FamilyFit, ...]:
        return tuple(sorted((family for family in self.families if family.said),
                            key=lambda family: sum(family.cross_fitted_ratio.values())))

    def line(self) -> str:
        """The summary line of ``oed predict``."""
        if not self.said:
            tested = " or ".join(("a payload on the last link" if family.name == "payload" else "gravity turned")
                                 for family in self.families)
            return f"changed since the training: nothing said ({tested} tested on this record)"
        return "changed since the training: " + "; ".join(
            f"{family.words()} (with it this record's MSE would be "
            + ", ".join(f"{channel} {value:.4g}" for channel, value in family.fitted_mse.items())
            + ", fitted on this record, not a held-out figure)" for family in self.said)

    def to_dict(self) -> dict[str, Any]:
        said = self.said
        return {"said": [family.to_dict() for family in said],
                "summary": self.line().removeprefix("changed since the training: "),
                "tested": {family.name: family.to_dict() for family in self.families},
                "floor_source": self.floor_source,
                "rule": f"said when the HAC Wald test gives p < {ALPHA:g} over the families, a channel's error "
                        f"cross-fitted between the record's halves is at most {MARK:g} of the model's and "
                        f"{MIN_FLOORS:g} noise floors less, and no channel's more than {WORSE_LIMIT:g} times and "
                        f"{WORSE_FLOORS:g} floors more; "
                        "the prediction is the model's own"}


def _rows(n_samples: int) -> NDArray[np.int64]:
    return np.unique(np.linspace(0, n_samples - 1, min(n_samples, MAX_SAMPLES)).astype(int))


def _segments(record: Measurements, rows: NDArray[np.int64]) -> list[tuple[int, int]]:
    """``(start, stop)`` in ``rows`` of each segment of ``record``."""
    bounds = []
    for piece in segment_slices(record):
        start, stop = np.searchsorted(rows, [piece.start, piece.stop])
        if stop > start:
            bounds.append((int(start), int(stop)))
    return bounds or [(0, rows.shape[0])]


def _solve(columns: NDArray, target: NDArray, weights: NDArray, scales: NDArray) -> tuple[NDArray, NDArray]:
    """``(β, A⁺)`` of the weighted least squares of ``target`` on ``columns`` (``(N, m, k)``), in coordinates scaled
    by ``scales``, the directions no sample determines left at zero."""
    A = np.einsum("nmi,m,nmj->ij", columns, weights, columns, optimize=True)
    b = np.einsum("nmi,m,nm->i", columns, weights, target, optimize=True)
    scaled = A * np.outer(scales, scales)
    values, vectors = np.linalg.eigh(0.5 * (scaled + scaled.T))
    kept = values > STRUCTURAL_TOLERANCE * max(values[-1], np.finfo(float).tiny)
    inverse = (vectors[:, kept] / values[kept]) @ vectors[:, kept].T * np.outer(scales, scales)
    return inverse @ b, inverse


def _mse(residual: NDArray, channels: tuple[str, ...]) -> dict[str, float]:
    return dict(zip(channels, map(float, np.mean(residual ** 2, axis=0))))


class _Family:
    """A family's columns along a record (``(N, m, k)``, in the log's units and directions) and its words."""

    name = ""
    scales: NDArray[np.float64] = np.ones(0)

    def columns(self, q: NDArray, dq: NDArray, ddq: NDArray) -> NDArray[np.float64]:
        raise NotImplementedError

    def change(self, beta: NDArray, q: NDArray, dq: NDArray, ddq: NDArray) -> NDArray[np.float64]:
        """The torques the change ``β`` adds along the motion."""
        return self.columns(q, dq, ddq) @ beta

    def refine(self, beta: NDArray, target: NDArray, columns: NDArray, weights: NDArray, q: NDArray
               ) -> tuple[NDArray, NDArray]:
        return _solve(columns, target, weights, self.scales)

    def bodies_cov(self, beta: NDArray, columns: NDArray, weights: NDArray, inverse: NDArray, q: NDArray
                   ) -> NDArray[np.float64]:
        """The estimate's covariance from the robot's bodies the family's columns are built from (none here)."""
        return np.zeros((beta.shape[0], beta.shape[0]))

    def describe(self, beta: NDArray, cov: NDArray) -> dict[str, Any]:
        raise NotImplementedError


class _Payload(_Family):
    name = "payload"
    scales = np.array([1.0] + [0.1] * 3 + [0.01] * 6)  # a 1 kg body 0.1 m from the frame

    def __init__(self, identified: IdentifiedModel, factors: NDArray) -> None:
        self.identified, self.factors = identified, factors
        self.link = identified.robot.n_joints
        self.joint = identified.robot.joint_names[-1]

    def columns(self, q, dq, ddq):
        return self.identified.link_columns(self.link, q, dq, ddq) * self.factors[None, :, None]

    def describe(self, beta, cov):
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        mass, mass_std = float(beta[0]), float(std[0])
        centre = beta[1:4] / mass if mass != 0 else np.full(3, np.nan)
        # the centre of mass's standard deviation by the delta method (mass and first moments)
        jacobian = np.zeros((3, 10))
        if mass != 0:
            jacobian[:, 0] = -beta[1:4] / mass ** 2
            jacobian[:, 1:4] = np.eye(3) / mass
        centre_std = np.sqrt(np.clip(np.diag(jacobian @ cov @ jacobian.T), 0.0, None))
        more = "more" if mass >= 0 else "less"
        words = (f"this record carries {abs(mass):.3g} ± {mass_std:.2g} kg {more} on link {self.link} "
                 f"({self.joint}) than the training did, its centre of mass at ["
                 + ", ".join(f"{1e3 * value:.0f} ± {1e3 * s:.0f}" for value, s in zip(centre, centre_std))
                 + "] mm in the link's frame (a payload picked up or put down? `oed payload` identifies it from "
                   "records made with it)")
        return {"words": words, "link": self.joint, "link_index": self.link, "mass": mass, "mass_std": mass_std,
                "com": centre.tolist(), "com_std": centre_std.tolist(),
                "parameters": dict(zip(PAYLOAD_NAMES, map(float, beta))),
                "parameters_std": dict(zip(PAYLOAD_NAMES, map(float, std)))}


class _Gravity(_Family):
    name = "gravity"
    scales = np.array([0.01, 0.01])  # about half a degree

    def __init__(self, identified: IdentifiedModel, factors: NDArray) -> None:
        self.identified, self.factors = identified, factors
        robot = identified.robot
        self.magnitude = float(np.linalg.norm(robot.gravity))
        self.declared = np.asarray(robot.gravity, dtype=float) / self.magnitude
        self.across = np.linalg.svd(self.declared[None, :])[2][1:]
        model = identified.model
        self.rigid = 10 * robot.n_joints  # the standard parameters come first in every model's columns
        self.evaluator = rest_regressors(robot, np.vstack([self.declared, self.across]) * self.magnitude)
        self.evaluated: dict[int, NDArray[np.float64]] = {}
        K = model.base.K
        nominal = model.nominal_parameters()
        theta = np.asarray(identified.theta, dtype=float)
        # the model's bodies: its base parameters, completed by the description's where the training saw nothing
        inverse = np.linalg.pinv(K)
        self.standard = (nominal + inverse @ (theta - K @ nominal))[:self.rigid]
        # how far the description is off where the training saw it (the base parameters of the bodies alone): the
        # relative error given to its share, the directions the training did not determine
        bodies = np.all(K[:, self.rigid:] == 0.0, axis=1)
        described = K[bodies] @ nominal
        self.description_error = float(np.linalg.norm(theta[bodies] - described)
                                       / max(np.linalg.norm(described), np.finfo(float).tiny)) if bodies.any() else 1.0
        unseen = (np.eye(K.shape[1]) - inverse @ K)[:self.rigid, :self.rigid]
        share = unseen * (self.description_error * nominal[:self.rigid])[None, :]
        self.description_cov = share @ share.T  # the description's share of the bodies: its covariance

    def loads(self, q: NDArray) -> NDArray[np.float64]:
        """``(N, m, 3)``: the gravity load along ``ĝ, e_1, e_2`` (the log's units)."""
        regressors = self.rest_regressors(q)
        return np.einsum("anmp,p->nma", regressors, self.standard)

    def rest_regressors(self, q: NDArray) -> NDArray[np.float64]:
        """``(3, N, m, p)``: the bodies' regressor at rest with gravity along ``ĝ, e_1, e_2`` (the log's units)."""
        q = np.ascontiguousarray(q, dtype=float)
        key = hash(q.tobytes())
        if key not in self.evaluated:  # the same rows are asked for by the fit, its covariance and its scores
            regressors = self.evaluator(q)  # (N, 3 n p): Yᵀ of each gravity, column-major
            regressors = regressors.reshape(q.shape[0], 3, q.shape[1], self.rigid).transpose(1, 0, 2, 3)
            self.evaluated = {key: regressors * self.factors[None, None, :, None]}  # the last rows only
        return self.evaluated[key]

    def bodies_cov(self, beta: NDArray, columns: NDArray, weights: NDArray, inverse: NDArray, q: NDArray
                   ) -> NDArray[np.float64]:
        """The estimate's covariance from the description's share of the bodies (what the training did not
        determine, taken from the description with the relative error it shows where the training saw it):
        ``S_d Σ_d S_dᵀ``, ``S_d = A⁺ Σ_c w_c C_cᵀ ∂(Δτ_c)/∂θ_s``."""
        regressors = self.rest_regressors(q)
        u0 = np.sqrt(max(1.0 - float(beta @ beta), 0.0))
        derivative = (u0 - 1.0) * regressors[0] + np.einsum("a,anmp->nmp", beta, regressors[1:])
        sensitivity = inverse @ np.einsum("nmi,m,nmp->ip", columns, weights, derivative, optimize=True)
        return sensitivity @ self.description_cov @ sensitivity.T

    def columns(self, q, dq, ddq):
        return self.loads(q)[:, :, 1:]

    def change(self, beta, q, dq, ddq):
        loads = self.loads(q)
        u0 = np.sqrt(max(1.0 - float(beta @ beta), 0.0))
        return (u0 - 1.0) * loads[:, :, 0] + loads[:, :, 1:] @ beta

    def refine(self, beta, target, columns, weights, q):
        """Gauss–Newton from level: the linear fit on ``G_1, G_2`` with the second-order term ``(u_0 − 1) G_0``
        moved to the target (three passes: a few degrees need one)."""
        along = self.loads(q)[:, :, 0]
        for _ in range(3):
            u0 = np.sqrt(max(1.0 - float(beta @ beta), 0.0))
            beta, inverse = _solve(columns, target - (u0 - 1.0) * along, weights, self.scales)
        return beta, inverse

    def describe(self, beta, cov):
        size = float(np.linalg.norm(beta))
        angle = float(np.degrees(np.arcsin(min(size, 1.0))))
        direction = beta / size if size > 0 else np.zeros(2)
        angle_std = float(np.degrees(np.sqrt(max(direction @ cov @ direction, 0.0))))
        u0 = np.sqrt(max(1.0 - size ** 2, 0.0))
        found = self.magnitude * (u0 * self.declared + beta @ self.across)
        roll, pitch, yaw = mount_rpy(found)
        shown = ", ".join(f"{value:.4g}" for value in found)
        words = (f"gravity {angle:.3g} ± {angle_std:.2g}° off the model's on this record, along ({shown}) m/s² in "
                 "the base frame (the base off level, or mounted otherwise than in the training? the mount as a URDF "
                 f"origin: rpy=\"{roll:.4f} {pitch:.4f} {yaw:.4f}\")")
        return {"words": words, "description_error": self.description_error, "tilt_deg": angle, "tilt_std_deg": angle_std, "gravity": found.tolist(),
                "rpy": [roll, pitch, yaw], "coefficients": beta.tolist(),
                "coefficients_std": np.sqrt(np.clip(np.diag(cov), 0.0, None)).tolist()}


def rest_regressors(robot: Any, gravities: NDArray[np.float64]) -> SampleEvaluator:
    """The bodies' joint-torque regressor at rest (``q̇ = q̈ = 0``: the gravity load per standard parameter) with
    gravity along each row of ``gravities`` (m/s², base frame), stacked: per sample ``[Y_1ᵀ, Y_2ᵀ, …]`` (``10 n`` by
    ``n`` each), one compiled function (:class:`~dynamics.codegen.compiled.SampleEvaluator`, cached on disk) and no
    base-parameter reduction, which a model of each gravity would cost (:func:`dynamics.models.build_model`).

    Built once per description: the function depends only on the chain's kinematics (each joint's type, axis,
    placement and link transform; not its inertials: a regressor is linear in them) and on ``gravities``, and is
    kept per that content (:func:`functools.lru_cache` on a key of their bytes; a robot loaded again from its
    description, as each ``oed predict`` does, finds it). The cached value is the same function the content
    builds, so the cache cannot change an answer."""
    gravities = np.atleast_2d(np.asarray(gravities, dtype=float))
    return _rest_regressors(_Described(robot, gravities))


@dataclass(frozen=True, eq=False)
class _Described:
    """A robot's kinematics and the gravities of :func:`rest_regressors`, compared and hashed by their content."""

    robot: Any
    gravities: NDArray[np.float64]

    @property
    def key(self) -> tuple[Any, ...]:
        joints = tuple((joint.joint_type.value, np.asarray(joint.axis, dtype=float).tobytes(),
                        np.asarray(joint.placement, dtype=float).tobytes(),
                        np.asarray(joint.link_transform, dtype=float).tobytes()) for joint in self.robot.joints)
        return joints, self.gravities.shape, self.gravities.tobytes()

    def __hash__(self) -> int:
        return hash(self.key)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, _Described) and self.key == other.key


@functools.lru_cache(maxsize=16)
def _rest_regressors(described: _Described) -> SampleEvaluator:
    robot, blocks, q = described.robot, [], None
    for gravity in described.gravities:
        rigid = rigid_body_regressors(robot.with_gravity(gravity))
        joint = casadi.substitute(rigid.joint, casadi.vertcat(rigid.dq, rigid.ddq), casadi.SX.zeros(2 * robot.n_joints))
        if q is None:
            q = rigid.q
        else:
            joint = casadi.substitute(joint, rigid.q, q)
        blocks.append(joint.T)
    function = casadi.Function("rest_regressors", [q], [casadi.cse(casadi.horzcat(*blocks))], ["q"], ["Yt"])
    return SampleEvaluator(function)


def check_record_changes(identified: IdentifiedModel, prepared: Measurements, prediction: Prediction,
                         floor: dict[str, float] | None) -> RecordChanges | None:
    """Test the residual of ``prediction`` (the model's along the prepared record ``prepared``) against a payload on
    the last link and gravity turned (module docstring); ``floor``: each channel's noise floor on the record (MSE;
    ``None``: the model's residual variance on its training record stands in). ``None``: nothing to check (the
    record holds no channels, or they are not all joint torques, or the model knows no gravity)."""
    channels = tuple(identified.channels)
    if prediction.measured is None or identified.model.kind is ModelKind.EXTERNAL \
            or not all(is_joint_torque(channel) for channel in channels):
        return None
    record = prepared if identified.delay is None else delayed(prepared, identified.delay)
    record = record.as_recorded
    if record.n_samples != prediction.t.shape[0] or record.n_samples < 20:
        return None
    residual = prediction.measured - prediction.predicted
    # the families' columns in the log's units and directions, as the prediction: times each channel's torque gain
    # and the sign it was read with
    factors = identified.file.channel_gains() * identified.channel_signs()
    floor_source = "this record's noise floor"
    if floor is None or not all(float(floor.get(channel, 0.0)) > 0 for channel in channels):
        floor = dict(zip(channels, map(float, np.asarray(identified.band_variance, dtype=float)
                                       * identified.file.channel_gains() ** 2)))
        floor_source = "the model's residual variance on its training record (no noise floor on this record)"
    floors = np.array([float(floor[channel]) for channel in channels])
    if not np.all(floors > 0):
        return None
    families: list[_Family] = [_Payload(identified, factors)]
    if np.linalg.norm(identified.robot.gravity) > 0 and identified.model.kind is ModelKind.INTERNAL \
            and len(channels) == identified.robot.n_joints:  # each joint's torque, in order: the bodies' rows
        families.append(_Gravity(identified, factors))
    rows = _rows(record.n_samples)
    q, dq, ddq = record.q[rows], record.dq[rows], record.ddq[rows]
    target = residual[rows]
    segments = _segments(record, rows)
    weights = 1.0 / floors
    jacobian = identified.regressor(q, dq, ddq) * factors[None, :, None]  # the prediction's in the model's θ
    fits = [_fitted(family, identified, record, residual, rows, target, weights, segments, jacobian, floors,
                    channels, len(families)) for family in families]
    return RecordChanges(tuple(fits), floor_source)


def _fitted(family: _Family, identified: IdentifiedModel, record: Measurements, residual: NDArray,
            rows: NDArray, target: NDArray, weights: NDArray, segments: list[tuple[int, int]], jacobian: NDArray,
            floors: NDArray, channels: tuple[str, ...], n_families: int) -> FamilyFit:
    q, dq, ddq = record.q[rows], record.dq[rows], record.ddq[rows]
    columns = family.columns(q, dq, ddq)
    beta, inverse = family.refine(np.zeros(columns.shape[-1]), target, columns, weights, q)
    explained = family.change(beta, q, dq, ddq)
    after = target - explained
    # the record's noise, correlated in time (HAC), and the model's own uncertainty through the target
    cov_noise, _ = hac_covariance(columns, after, weights, inverse, segments=segments)
    sensitivity = inverse @ np.einsum("nmi,m,nmr->ir", columns, weights, jacobian, optimize=True)
    cov = cov_noise + sensitivity @ identified.cov @ sensitivity.T + family.bodies_cov(beta, columns, weights,
                                                                                       inverse, q)
    test = wald_test(beta, cov)
    # cross-fitted halves: each half predicted by the coefficients fitted on the other
    half = target.shape[0] // 2
    crossed = np.empty_like(target)
    for fit_part, held_part in ((slice(half, None), slice(0, half)), (slice(0, half), slice(half, None))):
        part_beta, _ = family.refine(np.zeros(columns.shape[-1]), target[fit_part], columns[fit_part], weights,
                                     q[fit_part])
        crossed[held_part] = target[held_part] - family.change(part_beta, q[held_part], dq[held_part],
                                                               ddq[held_part])
    model_mse = _mse(target, channels)
    cross_mse = _mse(crossed, channels)
    # the error with the change fitted, on every sample of the record
    total = np.zeros(len(channels))
    for start in range(0, record.n_samples, CHUNK):
        piece = slice(start, min(start + CHUNK, record.n_samples))
        total += np.sum((residual[piece] - family.change(beta, record.q[piece], record.dq[piece],
                                                         record.ddq[piece])) ** 2, axis=0)
    fitted_mse = dict(zip(channels, map(float, total / record.n_samples)))
    model = np.array(list(model_mse.values()))
    crossed_values = np.array(list(cross_mse.values()))
    explains = np.any((crossed_values <= MARK * model) & (model - crossed_values >= MIN_FLOORS * floors))
    worse = np.any((crossed_values > WORSE_LIMIT * model) & (crossed_values - model > WORSE_FLOORS * floors))
    said = bool(test.p_value < ALPHA / n_families and explains and not worse)
    return FamilyFit(family.name, beta, cov, test.statistic, test.p_value, model_mse, cross_mse, fitted_mse,
                     dict(zip(channels, map(float, floors))), said, family.describe(beta, cov))
