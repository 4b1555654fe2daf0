"""Has the robot's load or mount changed since the training? A check of the record ``oed predict`` is given.

A model identified on one day predicts a record of another: a gripper may hold a part the training never saw, a
mobile base may stand off level. The model cannot know it, and the error alone does not say it. The check tests
the residual of the model's prediction ``r = y − ŷ`` on the record against small, physically named families
of what may have changed, each linear (or nearly) in a few parameters ``β``:

- **a payload on a link**: ``Y_k β``, ``Y_k`` the ten standard-parameter columns of link ``k`` (the
  Newton–Euler regressor, the columns ``oed payload`` fits, :mod:`estimation.payload.fit`), ``β`` a rigid body's
  mass, first moments and inertia about the link's frame (negative: a load taken off). Every link is tried
  (:func:`_payload_link`): the one whose payload, cross-fitted between the record's halves, leaves the least error
  is the best supported; another link is ruled out when the best one's columns explain what its own leave
  (:func:`_adds_to`, a Wald test of the part of the best link's columns square to the other's, ``p <``
  :data:`ALPHA`). The links not ruled out are named together (a point mass on a wrist joint's axis loads that
  joint's link and the one before it alike), the estimate given on the outermost of them; the payload's p-value is
  multiplied by the number of links tried;
- **gravity turned** (the base off level, or mounted otherwise): with ``ĝ`` the model's gravity direction and
  ``e_1, e_2`` two directions square to it, gravity ``|g| (u_0 ĝ + u_1 e_1 + u_2 e_2)``, ``u_0 = √(1 − u_1² − u_2²)``
  (:mod:`estimation.identification.mount`), so ``Δτ = (u_0 − 1) G_0 + u_1 G_1 + u_2 G_2``, ``G_a(q)`` the gravity
  load along each direction of the model's bodies: its base parameters completed by the description's for what the
  training left undetermined, ``θ_s = θ_nom + K⁺ (θ_b − K θ_nom)`` (``θ_b = K θ_s``). Two angles, fitted by
  Gauss–Newton from level. The description's share ``(I − K⁺K) θ_nom`` is given the relative error the description
  shows where the training saw it (``‖θ_b − K θ_nom‖ / ‖K θ_nom‖`` over the bodies' base parameters), propagated
  into the angles' covariance: on a simulated PUMA whose bodies are the description's ±20 %, the angle of a 2° tilt
  is 1.84° with the description's share, 1.98° with the true bodies;
  a payload is said only when its mass is seen (its own Wald test passes too: a change of a link's first moments
  and inertia alone is what the model's own error on that link's body looks like);
- **both together** (a load picked up and the base moved): the payload on its link and gravity turned fitted
  jointly, the payload's own load turned with gravity (``Δτ = Y_k β_p + Σ_a c_a (G_a + R_a β_p)``, ``R_a`` the link's
  columns at rest along each direction, ``c = (u_0 − 1, u_1, u_2)``; Gauss–Newton), the link chosen by the joint
  fit's own search (:func:`_together_link`: every link's joint fit cross-fitted, the others ruled out as for the
  payload alone; the payload alone may choose another link, a tilt's load taken up by an outer link's first
  moments). Said only when each part's coefficients pass the Wald test beside the other's and each part removes
  :data:`MIN_FLOORS` noise floors of some channel's cross-fitted error beyond the other family alone
  (:func:`_each_part_seen`); it is then named alone, neither family by itself.

Each family is fitted by weighted least squares (each channel weighted by its noise floor on this record) and said
only when all of these hold:

1. **its coefficients are far from zero for the noise of the record**: the Wald test ``W = βᵀ C⁻¹ β`` with ``C`` the
   prewhitened Newey–West covariance (:func:`estimation.uncertainty.covariance.hac_covariance`: residuals correlated
   in time) plus the model's own uncertainty propagated through the fit (``κ S Σ_θ Sᵀ``, as ``oed payload``) and,
   for gravity, the description's share of the bodies (above), at
   ``p <`` :data:`ALPHA` over the families (Bonferroni), the statistic the diagnosis adopts effects with
   (:mod:`estimation.diagnosis.rules.robust_test`);
2. **it explains most of the error on some channel, on samples its fit did not see**: the record's two halves
   cross-fitted (each half predicted with the coefficients fitted on the other, in the directions that half
   determines better than the family's scale, :data:`DETERMINED`), a channel's error at most
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
two families are said, the one with the lower cross-fitted error is named first.

**The model's own error on this motion** (``κ``, :func:`_model_scale`). The covariance ``Σ_θ`` of the training
holds the model's error from the training's noise, not what the model gets wrong on a motion it did not see: an
effect the training left out has its torque taken up by the bodies' parameters there, and on another motion that
error is smooth, does not average out over the samples, and a change fitted here takes part of it. After
``oed diagnose`` (which left the truth's offset on tau2 out: its torque is taken up on the training motion within
1 % of the noise) a 2 kg payload came out 1.9855 ± 0.0033 kg, 4.3 standard deviations low, and over eight draws
of the records 3.5 standard deviations low on average. ``Σ_θ`` is therefore scaled by
``κ = max(1, Σ_c (MSE_c − σ_c²)/σ_c² / Σ_c v_c/σ_c²)``: the error the record shows above its noise floor ``σ_c²``
once the change is fitted, over the error ``v_c`` the covariance predicts (the band's share of the parameters).
Over twelve draws the payload's standardised error has a root mean square of 1.0 after ``oed diagnose`` (0.5
after ``oed identify``, whose error the covariance held already: the scaled deviation is conservative there). Nothing in the prediction
changes: the error the model would have with the change is reported beside it, labelled as fitted on this record
(not a held-out figure).
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import casadi
import numpy as np
from numpy.typing import NDArray

from dynamics.channels import is_joint_torque
from dynamics.measurements import Measurements
from dynamics.codegen.compiled import SampleEvaluator
from dynamics.models import ModelKind
from dynamics.newton_euler import rigid_body_regressors
from dynamics.robot import ByDescription
from estimation.data.channel_mask import masked_rows
from estimation.data.segments import segment_slices
from estimation.uncertainty.wald import wald_test
from estimation.identification.mount import mount_rpy
from estimation.preprocessing.delay import delayed
from estimation.uncertainty.covariance import hac_covariance

if TYPE_CHECKING:
    from estimation.identification.identified_model import IdentifiedModel, Prediction

__all__ = ["ALPHA", "FITTED_LABEL", "MARK", "MIN_FLOORS", "WORSE_FLOORS", "WORSE_LIMIT", "FamilyFit", "RecordChanges",
           "RecordSample", "check_record_changes", "checked_channels", "record_segments", "rest_loads",
           "rest_regressors", "sampled_record_changes", "sampled_rows"]

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
#: the cross-fits leave at zero each direction of the scaled coefficients whose eigenvalue of the scaled normal
#: matrix (weighted by the noise floors) is below this: its standard deviation for the record's noise alone is
#: above the family's scale (a 1 kg body 0.1 m from the frame, 0.01 kg m²; half a degree), so the half fitted on
#: determines nothing there the other half could be predicted with (:func:`_crossed`)
DETERMINED = 1.0
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
            words = {"payload": "a payload on any link", "gravity": "gravity turned", "payload and gravity": "both"}
            tested = ", ".join(words.get(family.name, family.name) for family in self.families)
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
                "rule": f"said when the HAC Wald test (the model's covariance scaled by the error this record shows "
                        "above its noise floor; a payload's p-value times the links tried) gives p < "
                        f"{ALPHA:g} over the families, a channel's error "
                        f"cross-fitted between the record's halves is at most {MARK:g} of the model's and "
                        f"{MIN_FLOORS:g} noise floors less, and no channel's more than {WORSE_LIMIT:g} times and "
                        f"{WORSE_FLOORS:g} floors more; "
                        "the prediction is the model's own"}


def _rows(n_samples: int) -> NDArray[np.int64]:
    return np.unique(np.linspace(0, n_samples - 1, min(n_samples, MAX_SAMPLES)).astype(int))


def _segments(record: Measurements, rows: NDArray[np.int64]) -> list[tuple[int, int]]:
    """``(start, stop)`` in ``rows`` of each segment of ``record``."""
    return record_segments([(piece.start, piece.stop) for piece in segment_slices(record)], rows)


def _gram(left: NDArray, weights: NDArray, right: NDArray) -> NDArray[np.float64]:
    """``Σ_n Σ_c w_c L_ncᵀ R_nc`` of columns ``(N, m, a)`` and ``(N, m, b)`` (or targets ``(N, m)``), one matrix
    product; ``weights`` ``(m,)``, or ``(N, m)`` with a masked sample's equation weighted 0 (:func:`_masked_weights`)."""
    left = left.reshape(left.shape[0], left.shape[1], -1) * (weights[:, :, None] if weights.ndim == 2
                                                             else weights[None, :, None])
    right = right.reshape(right.shape[0], right.shape[1], -1)
    return left.reshape(-1, left.shape[2]).T @ right.reshape(-1, right.shape[2])


def _solve(columns: NDArray, target: NDArray, weights: NDArray, scales: NDArray, determined: float = 0.0
           ) -> tuple[NDArray, NDArray]:
    """``(β, A⁺)`` of the weighted least squares of ``target`` on ``columns`` (``(N, m, k)``), in coordinates scaled
    by ``scales``, the directions no sample determines left at zero; ``determined``: the directions whose eigenvalue
    of the scaled normal matrix is below it left at zero too (:data:`DETERMINED`: those the samples determine no
    better than the family's scale)."""
    A = _gram(columns, weights, columns)
    b = _gram(columns, weights, target)[:, 0]
    scaled = A * np.outer(scales, scales)
    values, vectors = np.linalg.eigh(0.5 * (scaled + scaled.T))
    kept = (values > STRUCTURAL_TOLERANCE * max(values[-1], np.finfo(float).tiny)) & (values >= determined)
    inverse = (vectors[:, kept] / values[kept]) @ vectors[:, kept].T * np.outer(scales, scales)
    return inverse @ b, inverse


def _model_variance(jacobian: NDArray, cov: NDArray, weights: NDArray) -> NDArray[np.float64]:
    """``(m,)``: the variance of each channel's prediction the model's covariance gives, averaged over the samples
    (each channel's valid ones: ``weights``) (``y_bᵀ Σ_θ y_b``, the band's share of the parameters)."""
    values, vectors = np.linalg.eigh(0.5 * (cov + cov.T))
    root = vectors * np.sqrt(np.clip(values, 0.0, None))[None, :]
    return _channel_mean(np.sum((jacobian @ root) ** 2, axis=2), weights)


def _masked_weights(target: NDArray, floors: NDArray) -> tuple[NDArray, NDArray]:
    """``(target, weights)`` of the families' weighted fits: ``1 / floors`` per channel and ``target`` as given
    when no sample is masked (the default path: nothing copied); else a sample's masked channel (NaN in ``target``:
    a clipped sensor's, :mod:`estimation.data.channel_mask`) weighted 0 in ``(N, m)`` weights and its target 0,
    which removes that equation, and that one only, from every weighted sum (the other channels of the sample
    stay)."""
    weights = 1.0 / floors
    valid = ~np.isnan(target)
    if valid.all():
        return target, weights
    return np.where(valid, target, 0.0), valid * weights[None, :]


def _valid(values: NDArray, weights: NDArray) -> NDArray:
    """``values`` ``(N, m)`` zero at the masked samples of ``weights`` (``(N, m)``; as given when ``(m,)``)."""
    return values if weights.ndim == 1 else np.where(weights > 0, values, 0.0)


def _channel_mean(values: NDArray, weights: NDArray) -> NDArray[np.float64]:
    """``(m,)`` each channel's mean of ``values`` ``(N, m)`` over its valid samples (``weights`` ``(N, m)`` above
    0; every sample when ``(m,)``)."""
    if weights.ndim == 1:
        return np.mean(values, axis=0)
    valid = weights > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(valid, values, 0.0).sum(axis=0) / valid.sum(axis=0)


def _rows_of(weights: NDArray, part: slice) -> NDArray:
    """``weights`` of the rows ``part`` (per channel when ``(m,)``: the same)."""
    return weights if weights.ndim == 1 else weights[part]


def _hac(columns: NDArray, after: NDArray, weights: NDArray, inverse: NDArray, segments: list[tuple[int, int]]
         ) -> NDArray[np.float64]:
    """:func:`~estimation.uncertainty.covariance.hac_covariance` of a fit with ``weights`` (``(N, m)``: a masked
    sample's equation adds no score, its residual taken as 0 beside the channel's weight)."""
    if weights.ndim == 2:
        after, weights = _valid(after, weights), weights.max(axis=0)
    cov, _ = hac_covariance(columns, after, weights, inverse, segments=segments)
    return cov


def _model_scale(after: NDArray, floors: NDArray, model_variance: NDArray, weights: NDArray) -> float:
    """``κ ≥ 1``, the model's covariance scaled so that the error it predicts on this record holds what the record
    shows above its noise floor once the change is fitted: ``κ = Σ_c (MSE_c − σ_c²)/σ_c² / Σ_c v_c/σ_c²`` (``v_c``:
    :func:`_model_variance`). A model's error on a motion it did not see is smooth and does not average out over
    the samples as noise does: where the training left an effect out (its torque taken up by the bodies' parameters
    there), the error on this motion is larger than the covariance of the training holds, and a change fitted here
    takes up part of it (module docstring: after ``oed diagnose`` a 2 kg payload came out 1.9855 ± 0.0033 kg)."""
    predicted = float(np.sum(model_variance / floors))
    if predicted <= 0.0:
        return 1.0
    excess = float(np.sum((_channel_mean(after ** 2, weights) - floors) / floors))
    return max(1.0, excess / predicted)


def _adds_to(extra: NDArray, extra_scales: NDArray, base: NDArray, base_scales: NDArray, target: NDArray,
             weights: NDArray, segments: list[tuple[int, int]], jacobian: NDArray, model_cov: NDArray
             ) -> tuple[float, int]:
    """``(p, k)``: does ``extra`` (``(N, m, k_e)`` columns) explain what ``base`` leaves of ``target``? The Wald test
    (HAC plus the model's own uncertainty, as the families') of ``extra``'s coefficients fitted on their part
    W-orthogonal to ``base`` (a score test of the larger model against ``base``), in the ``k`` directions of that
    part the samples determine (a direction of ``extra`` that ``base`` holds too carries no evidence either way:
    ``p = 1`` when none is left)."""
    beta, inverse = _solve(base, target, weights, base_scales)
    after_base = target - base @ beta
    projection = inverse @ _gram(base, weights, extra)
    orthogonal = extra - base @ projection
    reference = _gram(extra, weights, extra) * np.outer(extra_scales, extra_scales)
    scaled = _gram(orthogonal, weights, orthogonal) * np.outer(extra_scales, extra_scales)
    values, vectors = np.linalg.eigh(0.5 * (scaled + scaled.T))
    kept = values > STRUCTURAL_TOLERANCE * max(float(np.linalg.eigvalsh(reference)[-1]), np.finfo(float).tiny)
    if not kept.any():
        return 1.0, 0
    directions = orthogonal @ (vectors[:, kept] * extra_scales[:, None])
    inverse = np.diag(1.0 / values[kept])
    gamma = inverse @ _gram(directions, weights, after_base)[:, 0]
    after = after_base - directions @ gamma
    cov_noise = _hac(directions, after, weights, inverse, segments)
    sensitivity = inverse @ _gram(directions, weights, jacobian)
    test = wald_test(gamma, cov_noise + sensitivity @ model_cov @ sensitivity.T)
    return test.p_value, int(kept.sum())


def _mse(residual: NDArray, channels: tuple[str, ...], weights: NDArray) -> dict[str, float]:
    return dict(zip(channels, map(float, _channel_mean(residual ** 2, weights))))


class _Family:
    """A family's columns along a record (``(N, m, k)``, in the log's units and directions) and its words."""

    name = ""
    scales: NDArray[np.float64] = np.ones(0)

    def columns(self, q: NDArray, dq: NDArray, ddq: NDArray) -> NDArray[np.float64]:
        raise NotImplementedError

    def change(self, beta: NDArray, q: NDArray, dq: NDArray, ddq: NDArray) -> NDArray[np.float64]:
        """The torques the change ``β`` adds along the motion."""
        return self.columns(q, dq, ddq) @ beta

    def refine(self, beta: NDArray, target: NDArray, columns: NDArray, weights: NDArray, q: NDArray,
               determined: float = 0.0) -> tuple[NDArray, NDArray]:
        """``(β, A⁺)``: the family fitted to ``target`` (``determined``: as :func:`_solve`'s)."""
        return _solve(columns, target, weights, self.scales, determined)

    def bodies_cov(self, beta: NDArray, columns: NDArray, weights: NDArray, inverse: NDArray, q: NDArray
                   ) -> NDArray[np.float64]:
        """The estimate's covariance from the robot's bodies the family's columns are built from (none here)."""
        return np.zeros((beta.shape[0], beta.shape[0]))

    def parts(self, beta: NDArray, cov: NDArray) -> dict[str, float]:
        """The Wald p-value of each part of a family made of several (none here: the family is one change)."""
        return {}

    def describe(self, beta: NDArray, cov: NDArray) -> dict[str, Any]:
        raise NotImplementedError


class _StandardColumns:
    """The bodies' standard-parameter columns along a motion (``(N, m, 10 n)``, the log's units and directions),
    evaluated once for all the links' payloads (the last few motions kept: the fits, their halves and the
    record's blocks ask for the same rows again)."""

    KEPT = 4

    def __init__(self, identified: IdentifiedModel, factors: NDArray) -> None:
        self.identified, self.factors = identified, factors
        self.rigid = 10 * identified.robot.n_joints
        self.evaluated: dict[int, NDArray[np.float64]] = {}

    def __call__(self, q: NDArray, dq: NDArray, ddq: NDArray) -> NDArray[np.float64]:
        arrays = [np.ascontiguousarray(values, dtype=float) for values in (q, dq, ddq)]
        key = hash(b"".join(values.tobytes() for values in arrays) + str(arrays[0].shape).encode())
        if key not in self.evaluated:
            if len(self.evaluated) >= self.KEPT:
                self.evaluated.pop(next(iter(self.evaluated)))
            columns = self.identified.model.evaluate(*arrays)[:, :, :self.rigid]
            self.evaluated[key] = columns * self.factors[None, :, None]
        return self.evaluated[key]


class _Payload(_Family):
    name = "payload"
    scales = np.array([1.0] + [0.1] * 3 + [0.01] * 6)  # a 1 kg body 0.1 m from the frame

    def __init__(self, identified: IdentifiedModel, link: int, standard: _StandardColumns,
                 links: dict[str, Any] | None = None) -> None:
        """A payload on link ``link`` (1-based); ``links``: what the record says of each link (the words name the
        links it does not tell from this one)."""
        self.identified, self.link, self.standard = identified, int(link), standard
        self.joint = identified.robot.joint_names[self.link - 1]
        self.links = links or {}

    def columns(self, q, dq, ddq):
        start = 10 * (self.link - 1)
        return self.standard(q, dq, ddq)[:, :, start:start + 10]

    def parts(self, beta, cov):
        """A load is a body: its mass must be seen (a change the record shows only in a link's first moments and
        inertia, its mass undetermined or nought, is what the model's own error on that link's body looks like: a
        3-joint PUMA trained with a tool pressed on a table, its link 2 on the test record)."""
        return {"mass": wald_test(beta[:1], cov[:1, :1]).p_value}

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
        candidates = self.links.get("candidates", [self.joint])
        others = [name for name in candidates if name != self.joint]
        where = (f"link {self.link} ({self.joint})" if not others else
                 f"link {self.link} ({self.joint}; the record does not tell it from "
                 + ", ".join(others) + ": the load may be on any of these, given here in this link's frame)")
        words = (f"this record carries {abs(mass):.3g} ± {mass_std:.2g} kg {more} on {where} "
                 f"than the training did, its centre of mass at ["
                 + ", ".join(f"{1e3 * value:.0f} ± {1e3 * s:.0f}" for value, s in zip(centre, centre_std))
                 + "] mm in the link's frame (a payload picked up or put down? `oed payload` identifies it from "
                   "records made with it)")
        return {"words": words, "link": self.joint, "link_index": self.link, "mass": mass, "mass_std": mass_std,
                "com": centre.tolist(), "com_std": centre_std.tolist(),
                "parameters": dict(zip(PAYLOAD_NAMES, map(float, beta))),
                "parameters_std": dict(zip(PAYLOAD_NAMES, map(float, std))),
                "link_candidates": list(candidates), "links": self.links.get("links", {})}


class _Together(_Family):
    """A payload and gravity turned on the same record, fitted jointly (the payload's ten coefficients, then the
    gravity's two): said only when each part is needed beside the other.

    Gravity turns the payload's own load too: with ``R_a`` the payload link's ten columns at rest along ``ĝ, e_1,
    e_2`` (:meth:`_Gravity.rest_regressors`), ``Δτ = C β_p + Σ_a c_a (G_a + R_a β_p)``, ``c = (u_0 − 1, u_1, u_2)``:
    bilinear, fitted by Gauss–Newton from level and no payload."""

    name = "payload and gravity"

    def __init__(self, payload: _Payload, gravity: _Gravity) -> None:
        self.payload, self.gravity = payload, gravity
        self.scales = np.concatenate([payload.scales, gravity.scales])
        self.split = payload.scales.shape[0]
        self.turned: dict[int, NDArray[np.float64]] = {}

    def rest_columns(self, q: NDArray) -> NDArray[np.float64]:
        """``(N, m, 10, 3)``: the payload link's columns at rest along ``ĝ, e_1, e_2`` (the last few motions')."""
        q = np.ascontiguousarray(q, dtype=float)
        key = hash(q.tobytes() + str(q.shape).encode())
        if key not in self.turned:
            if len(self.turned) >= _StandardColumns.KEPT:
                self.turned.pop(next(iter(self.turned)))
            start = 10 * (self.payload.link - 1)
            units = np.zeros((10, q.shape[0], self.gravity.rigid))
            units[np.arange(10), :, start + np.arange(10)] = 1.0  # each column the load at rest of a unit parameter
            loads = self.gravity.rest_load(np.tile(q, (10, 1)), units.reshape(10 * q.shape[0], -1))
            self.turned[key] = np.ascontiguousarray(loads.reshape(10, q.shape[0], q.shape[1], 3).transpose(1, 2, 0, 3))
        return self.turned[key]

    def _coefficients(self, beta: NDArray) -> NDArray[np.float64]:
        turned = beta[self.split:]
        return np.concatenate([[np.sqrt(max(1.0 - float(turned @ turned), 0.0)) - 1.0], turned])

    def columns(self, q, dq, ddq):
        return np.concatenate([self.payload.columns(q, dq, ddq), self.gravity.columns(q, dq, ddq)], axis=2)

    def change(self, beta, q, dq, ddq):
        load, coefficients = beta[:self.split], self._coefficients(beta)
        turned_load = np.einsum("nmka,k,a->nm", self.rest_columns(q), load, coefficients, optimize=True)
        return self.payload.change(load, q, dq, ddq) + self.gravity.change(beta[self.split:], q, dq, ddq) \
            + turned_load

    def linearised(self, beta: NDArray, columns: NDArray, q: NDArray) -> tuple[NDArray, NDArray]:
        """``(J, Δτ)`` at ``β``: the change's Jacobian ``(N, m, 12)`` (the payload's columns turned with gravity,
        gravity's with the payload's load beside the bodies') and the change itself along the motion."""
        rest = self.rest_columns(q)
        load, coefficients = beta[:self.split], self._coefficients(beta)
        turned = np.einsum("nmka,a->nmk", rest, coefficients, optimize=True)
        with_load = self.gravity.loads(q) + np.einsum("nmka,k->nma", rest, load, optimize=True)  # (N, m, 3)
        u0 = coefficients[0] + 1.0
        # ∂Δτ/∂u_a = G'_a − (u_a / u_0) G'_0 (u_0 = √(1 − u_1² − u_2²)), G'_a the loads with the payload's beside
        gravity_columns = with_load[:, :, 1:] - with_load[:, :, :1] * (beta[self.split:] / max(u0, 1e-9))[None, None, :]
        linear = np.concatenate([columns[:, :, :self.split] + turned, gravity_columns], axis=2)
        return linear, columns[:, :, :self.split] @ load + with_load @ coefficients

    def refine(self, beta, target, columns, weights, q, determined=0.0):
        """Gauss–Newton from level and no payload: at each pass the change linearised about the last estimate
        (:meth:`linearised`), the second-order term moved to the target (three passes: a few degrees and kilograms
        need two)."""
        inverse = np.zeros((beta.shape[0], beta.shape[0]))
        for _ in range(3):
            linear, value = self.linearised(beta, columns, q)
            step, inverse = _solve(linear, target - value, weights, self.scales, determined)
            beta = beta + step
        return beta, inverse

    def bodies_cov(self, beta, columns, weights, inverse, q):
        return self.gravity.bodies_cov(beta[self.split:], columns, weights, inverse, q)

    def parts(self, beta, cov):
        parts = ((self.payload.name, slice(0, self.split)), (self.gravity.name, slice(self.split, None)))
        return {**{name: wald_test(beta[part], cov[part, part]).p_value for name, part in parts},
                **self.payload.parts(beta[:self.split], cov[:self.split, :self.split])}

    def describe(self, beta, cov):
        load = self.payload.describe(beta[:self.split], cov[:self.split, :self.split])
        turned = self.gravity.describe(beta[self.split:], cov[self.split:, self.split:])
        return {**turned, **load, "words": f"{load['words']}; and {turned['words']} (both fitted together)"}


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
        gravities = np.vstack([self.declared, self.across]) * self.magnitude
        self.evaluator, self.load_evaluator = rest_regressors(robot, gravities), rest_loads(robot, gravities)
        self.evaluated: dict[int, NDArray[np.float64]] = {}
        self.loaded: dict[int, NDArray[np.float64]] = {}
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
        """``(N, m, 3)``: the gravity load along ``ĝ, e_1, e_2`` (the log's units); the last few motions' kept (the
        fits, their halves and the record's blocks ask for the same rows again, alone and beside the payload)."""
        q = np.ascontiguousarray(q, dtype=float)
        key = hash(q.tobytes() + str(q.shape).encode())
        if key not in self.loaded:
            if len(self.loaded) >= _StandardColumns.KEPT:
                self.loaded.pop(next(iter(self.loaded)))
            self.loaded[key] = self.rest_load(q, self.standard)
        return self.loaded[key]

    def rest_load(self, q: NDArray, bodies: NDArray) -> NDArray[np.float64]:
        """``(N, m, 3)``: the load at rest of the standard parameters ``bodies`` with gravity along ``ĝ, e_1, e_2``
        (the log's units)."""
        bodies = np.broadcast_to(np.asarray(bodies, dtype=float), (q.shape[0], self.rigid))
        loads = self.load_evaluator(q, bodies).reshape(q.shape[0], 3, q.shape[1]).transpose(0, 2, 1)
        return loads * self.factors[None, :, None]

    def rest_regressors(self, q: NDArray) -> NDArray[np.float64]:
        """``(3, N, m, p)``: the bodies' regressor at rest with gravity along ``ĝ, e_1, e_2`` (the log's units)."""
        q = np.ascontiguousarray(q, dtype=float)
        key = hash(q.tobytes() + str(q.shape).encode())
        if key not in self.evaluated:  # the fit's rows are asked for by its loads and its covariance
            regressors = self.evaluator(q)  # (N, 3 n p): Yᵀ of each gravity, column-major
            regressors = regressors.reshape(q.shape[0], 3, q.shape[1], self.rigid).transpose(1, 0, 2, 3)
            regressors = np.ascontiguousarray(regressors * self.factors[None, None, :, None])
            self.evaluated = {key: regressors}  # the last rows only: (3, N, m, p)
        return self.evaluated[key]

    def bodies_cov(self, beta: NDArray, columns: NDArray, weights: NDArray, inverse: NDArray, q: NDArray
                   ) -> NDArray[np.float64]:
        """The estimate's covariance from the description's share of the bodies (what the training did not
        determine, taken from the description with the relative error it shows where the training saw it):
        ``S_d Σ_d S_dᵀ``, ``S_d = A⁺ Σ_c w_c C_cᵀ ∂(Δτ_c)/∂θ_s``."""
        regressors = self.rest_regressors(q)
        u0 = np.sqrt(max(1.0 - float(beta @ beta), 0.0))
        coefficients = np.concatenate([[u0 - 1.0], beta])  # ∂(Δτ)/∂θ_s = Σ_a c_a R_a
        sensitivity = inverse @ sum(coefficient * _gram(columns, weights, regressors[index])
                                    for index, coefficient in enumerate(coefficients))
        return sensitivity @ self.description_cov @ sensitivity.T

    def columns(self, q, dq, ddq):
        return self.loads(q)[:, :, 1:]

    def change(self, beta, q, dq, ddq):
        loads = self.loads(q)
        u0 = np.sqrt(max(1.0 - float(beta @ beta), 0.0))
        return (u0 - 1.0) * loads[:, :, 0] + loads[:, :, 1:] @ beta

    def refine(self, beta, target, columns, weights, q, determined=0.0):
        """Gauss–Newton from level: the linear fit on ``G_1, G_2`` with the second-order term ``(u_0 − 1) G_0``
        moved to the target (three passes: a few degrees need one)."""
        along = self.loads(q)[:, :, 0]
        for _ in range(3):
            u0 = np.sqrt(max(1.0 - float(beta @ beta), 0.0))
            beta, inverse = _solve(columns, target - (u0 - 1.0) * along, weights, self.scales, determined)
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

    Built once per description and ``gravities`` (:class:`dynamics.robot.ByDescription`, as
    :func:`dynamics.newton_euler.rigid_body_regressors`; a robot loaded again from its description, as each
    ``oed predict`` does, finds it). The cached value is the same function the content builds, so the cache cannot
    change an answer."""
    gravities = np.atleast_2d(np.asarray(gravities, dtype=float))
    return _rest_functions(ByDescription(robot), gravities.shape, gravities.tobytes())[0]


def rest_loads(robot: Any, gravities: NDArray[np.float64]) -> SampleEvaluator:
    """The gravity load at rest of bodies ``θ_s`` (``10 n`` standard parameters, an input per sample as ``q``) with
    gravity along each row of ``gravities``: per sample ``[Y_1 θ_s, Y_2 θ_s, …]`` (``n`` each), the product of
    :func:`rest_regressors` with ``θ_s`` without its ``10 n`` columns per sample; built and kept alike."""
    gravities = np.atleast_2d(np.asarray(gravities, dtype=float))
    return _rest_functions(ByDescription(robot), gravities.shape, gravities.tobytes())[1]


@functools.lru_cache(maxsize=16)
def _rest_functions(described: ByDescription, shape: tuple[int, ...], gravities_bytes: bytes
                    ) -> tuple[SampleEvaluator, SampleEvaluator]:
    robot, blocks, q = described.robot, [], None
    for gravity in np.frombuffer(gravities_bytes, dtype=float).reshape(shape):
        rigid = rigid_body_regressors(robot.with_gravity(gravity))
        joint = casadi.substitute(rigid.joint, casadi.vertcat(rigid.dq, rigid.ddq), casadi.SX.zeros(2 * robot.n_joints))
        if q is None:
            q = rigid.q
        else:
            joint = casadi.substitute(joint, rigid.q, q)
        blocks.append(joint)
    theta = casadi.SX.sym("theta", 10 * robot.n_joints)
    regressors = casadi.Function("rest_regressors", [q], [casadi.cse(casadi.horzcat(*(block.T for block in blocks)))],
                                 ["q"], ["Yt"])
    loads = casadi.Function("rest_loads", [q, theta], [casadi.cse(casadi.horzcat(*(block @ theta for block in blocks)))],
                            ["q", "theta"], ["tau"])
    return SampleEvaluator(regressors), SampleEvaluator(loads)


@dataclass(frozen=True)
class RecordSample:
    """The samples of a record the check fits its families on (:func:`sampled_rows` of the record's samples in
    their order, the motion moved by the model's delay as the prediction moves it) and how many the record holds.

    Attributes
    ----------
    q, dq, ddq
        ``(n, joints)`` the motion at those samples.
    target
        ``(n, channels)`` the residual of the model's prediction there (as recorded minus predicted, in the log's
        directions).
    segments
        ``(start, stop)`` in the rows of each segment of the record (:func:`record_segments`).
    n_samples
        The samples of the whole record; the rows are all of them when it holds at most :data:`MAX_SAMPLES`.
    channel_samples
        ``(channels,)`` the samples of the whole record each channel's errors are taken on (its valid ones: a
        masked sample, NaN in ``target``, drops that channel's equation only); ``None``: every sample.
    """

    q: NDArray[np.float64]
    dq: NDArray[np.float64]
    ddq: NDArray[np.float64]
    target: NDArray[np.float64]
    segments: list[tuple[int, int]]
    n_samples: int
    channel_samples: NDArray[np.int64] | None = None

    @property
    def whole(self) -> bool:
        """Whether the rows are every sample of the record."""
        return self.q.shape[0] == self.n_samples


#: the squared errors over every sample of the record, summed per channel, with each ``(family, coefficients)``'s
#: change removed from the residual (the families' ``change``): one ``(channels,)`` array each
SquaredWithChanges = Callable[[list[tuple[Any, NDArray[np.float64]]]], list[NDArray[np.float64]]]


def sampled_rows(n_samples: int) -> NDArray[np.int64]:
    """The rows of a record of ``n_samples`` samples the families are fitted on: at most :data:`MAX_SAMPLES`,
    evenly spaced (every one of a shorter record)."""
    return _rows(n_samples)


def record_segments(bounds: Sequence[tuple[int, int]], rows: NDArray[np.int64]) -> list[tuple[int, int]]:
    """``(start, stop)`` in ``rows`` of each segment whose samples are ``bounds`` (``(start, stop)`` in the
    record)."""
    segments = []
    for first, stop_at in bounds:
        start, stop = np.searchsorted(rows, [first, stop_at])
        if stop > start:
            segments.append((int(start), int(stop)))
    return segments or [(0, rows.shape[0])]


def checked_channels(identified: IdentifiedModel) -> bool:
    """Whether the check applies to the model's channels (an internal model, every channel a joint torque)."""
    return identified.model.kind is not ModelKind.EXTERNAL and all(is_joint_torque(channel)
                                                                   for channel in identified.channels)


def check_record_changes(identified: IdentifiedModel, prepared: Measurements, prediction: Prediction,
                         floor: dict[str, float] | None) -> RecordChanges | None:
    """Test the residual of ``prediction`` (the model's along the prepared record ``prepared``) against a payload on
    the last link and gravity turned (module docstring); ``floor``: each channel's noise floor on the record (MSE;
    ``None``: the model's residual variance on its training record stands in). ``None``: nothing to check (the
    record holds no channels, or they are not all joint torques, or the model knows no gravity)."""
    if prediction.measured is None or not checked_channels(identified):
        return None
    record = prepared if identified.delay is None else delayed(prepared, identified.delay)
    record = record.as_recorded
    if record.n_samples != prediction.t.shape[0] or record.n_samples < 20:
        return None
    residual = prediction.measured - prediction.predicted
    rows = _rows(record.n_samples)
    # a channel's masked samples (a clipped sensor's, NaN): that channel's equation of the sample left out only
    masked = masked_rows(residual)
    counts = None if masked is None else np.sum(~np.isnan(residual), axis=0)
    if counts is not None and np.any(np.sum(~np.isnan(residual[rows]), axis=0) < 20):
        return None
    sample = RecordSample(record.q[rows], record.dq[rows], record.ddq[rows], residual[rows],
                          _segments(record, rows), record.n_samples, counts)

    def squared(changes: list[tuple[Any, NDArray[np.float64]]]) -> list[NDArray[np.float64]]:
        totals = [np.zeros(residual.shape[1]) for _ in changes]
        for start in range(0, record.n_samples, CHUNK):
            piece = slice(start, min(start + CHUNK, record.n_samples))
            for total, (family, beta) in zip(totals, changes):
                error = (residual[piece] - family.change(beta, record.q[piece], record.dq[piece],
                                                         record.ddq[piece])) ** 2
                total += np.sum(error if masked is None else np.where(np.isnan(residual[piece]), 0.0, error), axis=0)
        return totals

    return sampled_record_changes(identified, sample, floor, squared)


def sampled_record_changes(identified: IdentifiedModel, sample: RecordSample, floor: dict[str, float] | None,
                           squared: SquaredWithChanges) -> RecordChanges | None:
    """:func:`check_record_changes` on the rows of ``sample`` (a record read whole, or read in blocks:
    :mod:`estimation.streaming.prediction`); ``squared``: the error with each family's change on every sample of the
    record (not called when the rows are every sample: the fit's own residual then)."""
    channels = tuple(identified.channels)
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
    target, weights = _masked_weights(sample.target, floors)
    sample = dataclasses.replace(sample, target=target)
    q, dq, ddq, segments = sample.q, sample.dq, sample.ddq, sample.segments
    jacobian = identified.regressor(q, dq, ddq) * factors[None, :, None]  # the prediction's in the model's θ
    standard = _StandardColumns(identified, factors)
    model_variance = _model_variance(jacobian, identified.cov, weights)
    payload = _payload_link(identified, standard, q, dq, ddq, target, weights, floors, segments, jacobian,
                            model_variance)
    families: list[_Family] = [payload]
    if np.linalg.norm(identified.robot.gravity) > 0 and identified.model.kind is ModelKind.INTERNAL \
            and len(channels) == identified.robot.n_joints:  # each joint's torque, in order: the bodies' rows
        gravity = _Gravity(identified, factors)
        families += [gravity, _together_link(identified, standard, gravity, payload, q, dq, ddq, target, weights,
                                             floors, segments, jacobian, model_variance)]
    searched = {family.name: identified.robot.n_joints if isinstance(family, _Payload) else 1 for family in families}
    fitted = [_estimated(family, sample, weights) for family in families]
    if sample.whole:  # the error with the change fitted, on every sample: the fit's own
        totals = [np.sum(_valid(after, weights) ** 2, axis=0) for _, _, after, _ in fitted]
    else:
        totals = squared([(family, estimate[0]) for family, estimate in zip(families, fitted)])
    fits = [_fitted(family, identified, sample, estimate, total, weights, jacobian, model_variance, floors, channels,
                    len(families), searched[family.name])
            for family, estimate, total in zip(families, fitted, totals)]
    fits = [_each_part_seen(fit, fits, floors) if fit.name == _Together.name else fit for fit in fits]
    if any(fit.said for fit in fits if fit.name == _Together.name):  # both needed: said together, not each alone
        fits = [fit if fit.name == _Together.name else dataclasses.replace(fit, said=False) for fit in fits]
    return RecordChanges(tuple(fits), floor_source)


def _each_part_seen(together: FamilyFit, fits: list[FamilyFit], floors: NDArray) -> FamilyFit:
    """``together`` said only when each part adds what the other alone leaves, on samples its fit did not see: its
    cross-fitted error at least :data:`MIN_FLOORS` noise floors below each family's alone on some channel (the
    effect size of condition 2, asked of each part as the Wald test of each part asks its significance).

    Without it a record holding a 1.2 kg payload and no tilt was said to hold both, gravity 0.018 ± 0.004° off
    (p = 4e-5): the model's own error on that motion, 0.02 noise floors on any channel, taken up by the two
    angles beside the payload (the PUMA 560 of ``tests/test_record_changes.py``, one motion of six)."""
    if not together.said:
        return together
    crossed = np.array(list(together.cross_fitted_mse.values()))
    added = {fit.name: float(np.max((np.array(list(fit.cross_fitted_mse.values())) - crossed) / floors))
             for fit in fits if fit.name != together.name}
    seen = all(value >= MIN_FLOORS for value in added.values())
    return dataclasses.replace(together, said=seen, details={**together.details, "parts_added_floors": added})


def _crossed(family: _Family, target: NDArray, columns: NDArray, weights: NDArray, q: NDArray, dq: NDArray,
             ddq: NDArray) -> NDArray[np.float64]:
    """The residual with the change cross-fitted between the record's halves: each half predicted by the
    coefficients fitted on the other, in the directions that half determines (:data:`DETERMINED`).

    A half may barely move some joint (a point-to-point record whose wrist rests through its first half): the
    payload's inertia about it is then fitted to the noise, tens of times the family's scale, and predicts the other
    half wildly. On the unseen robot's 2 kg payload (one of twelve draws) the first half's fit put −0.5 to −0.8 kg m²
    in the payload's inertia (their standard deviation 11-77 times the 0.01 kg m² scale) and made tau5 on the
    second half 22 noise floors worse; the whole record's fit predicts that half at its floor. The check then said
    nothing of a payload that lowers tau2's error 1800 floors. The directions left out carry no prediction either way,
    so an unchanged record's cross-fitted error is not lowered by leaving them out beyond the noise they would add."""
    half = target.shape[0] // 2
    crossed = np.empty_like(target)
    for fit_part, held_part in ((slice(half, None), slice(0, half)), (slice(0, half), slice(half, None))):
        part_beta, _ = family.refine(np.zeros(columns.shape[-1]), target[fit_part], columns[fit_part],
                                     _rows_of(weights, fit_part), q[fit_part], DETERMINED)
        crossed[held_part] = target[held_part] - (columns[held_part] @ part_beta if isinstance(family, _Payload)
                                                  else family.change(part_beta, q[held_part], dq[held_part],
                                                                     ddq[held_part]))
    return _valid(crossed, weights)


def _payload_link(identified: IdentifiedModel, standard: _StandardColumns, q: NDArray, dq: NDArray, ddq: NDArray,
                  target: NDArray, weights: NDArray, floors: NDArray, segments: list[tuple[int, int]],
                  jacobian: NDArray, model_variance: NDArray) -> _Payload:
    """The payload on the link the record supports best, or on the outermost of those it does not tell apart.

    Each link's payload is cross-fitted between the record's halves (:func:`_crossed`) and scored by its channels'
    errors over their noise floors; the best scored is compared with every other link ``k``: ``k`` is ruled out when
    the best link's columns explain, at ``p <`` :data:`ALPHA`, what ``k``'s leave (:func:`_adds_to`). The links not
    ruled out are those the record cannot tell from the best (a body on a wrist joint's axis loads that joint's link
    and the one before it alike); the payload is fitted on the outermost of them (a load is most often on the tool)
    and its words name the others. The order the links are tried in does not change the answer."""
    links = [_Payload(identified, link, standard) for link in range(1, identified.robot.n_joints + 1)]
    columns = [link.columns(q, dq, ddq) for link in links]
    errors = [_channel_mean(_crossed(link, target, link_columns, weights, q, dq, ddq) ** 2, weights)
              for link, link_columns in zip(links, columns)]
    scores = [float(np.sum(error / floors)) for error in errors]
    best = int(np.argmin(scores))
    beta, _ = links[best].refine(np.zeros(10), target, columns[best], weights, q)
    scale = _model_scale(target - columns[best] @ beta, floors, model_variance, weights)
    model = _channel_mean(target ** 2, weights)
    # where no link's payload explains most of some channel's error (condition 2 of the module docstring) none is
    # said, whichever the link: the links are not told apart (every one a candidate, none tested)
    explains = bool(np.any((errors[best] <= MARK * model) & (model - errors[best] >= MIN_FLOORS * floors)))
    evidence, candidates = {}, []
    for index, link in enumerate(links):
        p_value, directions = (1.0, 0) if index == best or not explains else _adds_to(
            columns[best], links[best].scales, columns[index], link.scales, target, weights, segments, jacobian,
            scale * identified.cov)
        evidence[link.joint] = {"cross_fitted_error_floors": scores[index] / len(floors),
                                "best_link_adds_p_value": p_value, "directions_tested": directions,
                                "ruled_out": bool(p_value < ALPHA), "tested": explains and index != best}
        if p_value >= ALPHA:
            candidates.append(index)
    chosen = max(candidates)
    return _Payload(identified, chosen + 1, standard,
                    {"candidates": [links[index].joint for index in sorted(candidates, reverse=True)],
                     "best_supported": links[best].joint, "links": evidence, "model_cov_scale": scale})


def _together_link(identified: IdentifiedModel, standard: _StandardColumns, gravity: _Gravity, payload: _Payload,
                   q: NDArray, dq: NDArray, ddq: NDArray, target: NDArray, weights: NDArray, floors: NDArray,
                   segments: list[tuple[int, int]], jacobian: NDArray, model_variance: NDArray) -> _Together:
    """The payload and gravity turned fitted together, the payload on the link the joint fit supports best, or on
    the outermost of those it does not tell apart (as :func:`_payload_link` for the payload alone).

    The payload alone may choose another link than the joint fit: a tilt's gravity load on the shoulder and elbow
    is partly what a payload on an inner link's first moments gives, so a payload on link 3 with the base 2° off
    level came out on link 4, 1.41 kg for 1.2, and nothing was said. Every link's joint fit is cross-fitted between
    the record's halves and scored by its channels' errors over their noise floors; link ``k`` is ruled out when
    the best link's payload columns (turned with its fitted gravity) explain, at ``p <`` :data:`ALPHA`, what
    ``k``'s joint fit leaves (:func:`_adds_to`, on the columns linearised at ``k``'s estimate: a score test of
    the larger model). The links are searched only where the payload alone (on some link) or gravity turned alone
    explains most of some channel's error (condition 2 of the module docstring, cross-fitted), as the payload's
    links are tested only where it explains; elsewhere the payload alone's link is kept. The order the links are
    tried in does not change the answer."""
    model = _channel_mean(target ** 2, weights)

    def scored(family: _Family) -> tuple[float, bool]:
        error = _channel_mean(_crossed(family, target, family.columns(q, dq, ddq), weights, q, dq, ddq) ** 2,
                              weights)
        explains = bool(np.any((error <= MARK * model) & (model - error >= MIN_FLOORS * floors)))
        return float(np.sum(error / floors)), explains

    if not (any(evidence["tested"] for evidence in payload.links.get("links", {}).values()) or scored(gravity)[1]):
        return _Together(payload, gravity)
    families = {link: _Together(_Payload(identified, link, standard), gravity)
                for link in range(1, identified.robot.n_joints + 1)}
    scores = {link: scored(family) for link, family in families.items()}
    best = min(families, key=lambda link: (scores[link][0], link))
    fits = {}
    for link, family in families.items():
        columns = family.columns(q, dq, ddq)
        beta, _ = family.refine(np.zeros(columns.shape[-1]), target, columns, weights, q)
        linear, value = family.linearised(beta, columns, q)
        fits[link] = (linear, target - value)
    scale = _model_scale(fits[best][1], floors, model_variance, weights)
    extra = fits[best][0][:, :, :families[best].split]  # the best link's payload columns, turned with its gravity
    evidence, candidates = {}, []
    for link, family in families.items():
        p_value, directions = (1.0, 0) if link == best else _adds_to(
            extra, family.payload.scales, fits[link][0], family.scales, fits[link][1], weights, segments, jacobian,
            scale * identified.cov)
        evidence[family.payload.joint] = {"cross_fitted_error_floors": scores[link][0] / len(floors),
                                          "best_link_adds_p_value": p_value, "directions_tested": directions,
                                          "ruled_out": bool(p_value < ALPHA), "tested": link != best}
        if p_value >= ALPHA:
            candidates.append(link)
    chosen = max(candidates)
    together = _Together(_Payload(identified, chosen, standard,
                                  {"candidates": [families[link].payload.joint
                                                  for link in sorted(candidates, reverse=True)],
                                   "best_supported": families[best].payload.joint, "links": evidence,
                                   "model_cov_scale": scale}), gravity)
    together.turned = families[chosen].turned  # the link's columns at rest, already evaluated on these rows
    return together


def _estimated(family: _Family, sample: RecordSample, weights: NDArray
               ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """``family`` fitted on the rows of ``sample``: its coefficients, the inverse of its normal matrix, the
    residual with the change removed and the family's columns there."""
    columns = family.columns(sample.q, sample.dq, sample.ddq)
    beta, inverse = family.refine(np.zeros(columns.shape[-1]), sample.target, columns, weights, sample.q)
    return beta, inverse, _valid(sample.target - family.change(beta, sample.q, sample.dq, sample.ddq), weights), \
        columns


def _fitted(family: _Family, identified: IdentifiedModel, sample: RecordSample,
            estimate: tuple[NDArray, NDArray, NDArray, NDArray], total: NDArray, weights: NDArray, jacobian: NDArray,
            model_variance: NDArray, floors: NDArray, channels: tuple[str, ...], n_families: int,
            searched: int = 1) -> FamilyFit:
    """``family`` tested (module docstring) at its fit ``estimate`` (:func:`_estimated`); ``total``: the squared
    error with its change over every sample of the record; ``searched``: how many variants the family was chosen
    among (a payload's links): its p-value multiplied by it (Bonferroni)."""
    q, dq, ddq, target = sample.q, sample.dq, sample.ddq, sample.target
    beta, inverse, after, columns = estimate
    # the record's noise, correlated in time (HAC), and the model's own uncertainty through the target
    cov_noise = _hac(columns, after, weights, inverse, sample.segments)
    sensitivity = inverse @ _gram(columns, weights, jacobian)
    scale = _model_scale(after, floors, model_variance, weights)
    cov = cov_noise + scale * sensitivity @ identified.cov @ sensitivity.T + family.bodies_cov(beta, columns, weights,
                                                                                               inverse, q)
    test = wald_test(beta, cov)
    p_value = min(1.0, test.p_value * searched)
    crossed = _crossed(family, target, columns, weights, q, dq, ddq)
    model_mse = _mse(target, channels, weights)
    cross_mse = _mse(crossed, channels, weights)
    counts = sample.n_samples if sample.channel_samples is None else sample.channel_samples
    fitted_mse = dict(zip(channels, map(float, total / counts)))

    model = np.array(list(model_mse.values()))
    crossed_values = np.array(list(cross_mse.values()))
    explains = np.any((crossed_values <= MARK * model) & (model - crossed_values >= MIN_FLOORS * floors))
    worse = np.any((crossed_values > WORSE_LIMIT * model) & (crossed_values - model > WORSE_FLOORS * floors))
    parts = family.parts(beta, cov)
    needed = all(value < ALPHA / n_families for value in parts.values())
    said = bool(p_value < ALPHA / n_families and explains and not worse and needed)
    details = {**family.describe(beta, cov), "model_cov_scale": scale}
    if parts:
        details["parts_p_value"] = parts
    return FamilyFit(family.name, beta, cov, test.statistic, p_value, model_mse, cross_mse, fitted_mse,
                     dict(zip(channels, map(float, floors))), said, details)
