"""Payload identification: a rigid body fixed to one link, from records made with it, the robot's model held fixed.

With the robot's identified model (``oed identify`` / ``oed diagnose``, friction and all) predicting ``ŷ_R =
Y_b θ_b`` (:class:`estimation.identification.identified_model.IdentifiedModel`), a payload fixed to link ``k``
adds its ten standard parameters ``π`` to that link's: the measured channels are

.. math::  y = Y_b θ_b + Y_k π + e ,

``Y_k`` the link's ten columns of the Newton–Euler regressor (PUMA paper, eqs. 1–13; link frame ``F_k``). The
target ``r = y − Y_b θ_b`` is fitted by weighted least squares, ``w_c = 1/σ_c²`` per channel (two passes: the
robot model's channel variances, then the residual variances of the first pass),

.. math::  \\hat π = A^{+} Σ_c w_c Y_{k,c}^T r_c ,\\qquad A = Σ_c w_c Y_{k,c}^T Y_{k,c} ,

solved in scaled parameters (mass, mass x length, mass x length²) so that a direction the data do not see is
left at zero rather than guessed. Uncertainty, two independent parts added:

- the record's noise: ``Σ_e = A⁺`` (the ``σ_c²`` estimated from the residuals), or by default its Newey–West
  sandwich, which holds when the residuals are correlated in time (:mod:`estimation.uncertainty.covariance`);
- the robot model's own: ``θ_b`` is an estimate, ``Σ_R = G Σ_θ Gᵀ`` with ``G = A⁺ Σ_c w_c Y_{k,c}^T Y_{b,c}``
  (the payload estimate's sensitivity to the robot's parameters through the target). No payload experiment
  shrinks this part.

A physically consistent body (mass > 0, inertia about the centre of mass positive definite, triangle
inequalities: the pseudo-inertia positive definite, :mod:`dynamics.physical_parameters`) is the least-squares
estimate when it is one; otherwise the nearest consistent body in the metric ``A`` (IPOPT on the lifted
Cholesky factorisation ``J = U Uᵀ`` of Rucker & Wensing 2022, as :mod:`estimation.consistent.solver` does for
whole robots), reported as such. With a known mass (``mass=M``: the payload was weighed) ``m = M`` and the nine
others are fitted.

Refused, with :class:`PayloadError`: a link that does not exist, records of another robot (more joints than
the model's, or residuals far above the model's own noise after the fit), records without the payload (a mass
estimate not clearly above zero), a model file that already carries a payload.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import casadi
import numpy as np
import pandas as pd
from numpy.typing import NDArray

from dynamics.measurements import Measurements
from dynamics.physical_parameters import consistency_margin, link_from_psi, log_cholesky_from_link, project_link
from dynamics.robot import LINK_PARAMETER_NAMES
from estimation.identification.identified_model import IdentifiedModel
from estimation.data.compressed_logs import csv_input, data_suffix
from estimation.data.segments import segment_slices
from estimation.preprocessing.delay import delayed
from estimation.uncertainty.covariance import CovarianceMethod, check_method, hac_covariance
from estimation.payload.body import PayloadBody

__all__ = ["MISMATCH_RATIO", "NO_PAYLOAD_SIGMAS", "RELATIVE_STD_THRESHOLD", "STD_NOTE", "PayloadError",
           "PayloadResult", "PayloadRows", "identify_payload", "payload_rows", "resolve_link"]

#: a parameter known to a standard deviation above this fraction of its scale (mass, mass x length, mass x length²)
#: is undetermined
RELATIVE_STD_THRESHOLD = 1.0
#: a mass estimate fewer standard deviations above zero than this: the records show no payload
NO_PAYLOAD_SIGMAS = 3.0
#: residual variance after the payload fit above this multiple of the robot model's own channel variance: the
#: model does not explain the records (another robot's model, or another set-up)
MISMATCH_RATIO = 25.0
#: the length below which a payload's centre of mass does not set its scale, m (a tool's size)
MIN_LENGTH = 0.1
#: eigenvalues of the scaled information below this fraction of the largest are zero (no record determines them)
STRUCTURAL_TOLERANCE = 1e-10
STD_NOTE = ("std: the record's torque noise and the robot model's own uncertainty (its parameters' covariance "
            "propagated through its prediction), independent, variances added; each part under std_parts")


class PayloadError(ValueError):
    """Input that cannot give a payload: an unknown link, another robot's records, records without the payload."""


# ---------------------------------------------------------------------------------------------- the link

def _urdf_child_links(model: IdentifiedModel) -> dict[str, str]:
    """URDF child-link name to joint name (empty for a built-in robot)."""
    source = model.file.robot
    text = source.urdf_text
    if text is None and source.urdf_path is not None and Path(source.urdf_path).is_file():
        text = Path(source.urdf_path).read_text()
    if text is None:
        return {}
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError:
        return {}
    links = {}
    for joint in root.iter("joint"):
        child = joint.find("child")
        if child is not None and joint.get("name") in model.robot.joint_names:
            links[str(child.get("link"))] = str(joint.get("name"))
    return links


def resolve_link(model: IdentifiedModel, link: str | int | None) -> tuple[int, str]:
    """``(k, joint name)``: the link a payload is fixed to, 1-based. ``None``: the last; a URDF link name, the name of
    the joint that moves it, ``link<k>`` or ``k``."""
    names = list(model.robot.joint_names)
    if link is None:
        return len(names), names[-1]
    if isinstance(link, (int, np.integer)) and not isinstance(link, bool):
        key = str(int(link))
    elif isinstance(link, str):
        key = link.strip()
    else:
        raise TypeError(f"link must be a name or a 1-based index, got {type(link).__name__}")
    children = _urdf_child_links(model)
    if key in children:
        joint = children[key]
        return names.index(joint) + 1, joint
    if key in names:
        return names.index(key) + 1, key
    index = key.removeprefix("link")
    if index.isdigit() and 1 <= int(index) <= len(names):
        return int(index), names[int(index) - 1]
    accepted = ", ".join(list(children) + names)
    raise PayloadError(f"no link {key!r} on {model.robot.name}: name a link or the joint that moves it ({accepted}), "
                       f"or link1..link{len(names)}")


# ---------------------------------------------------------------------------------------------- the rows

@dataclass(frozen=True)
class PayloadRows:
    """What one set of records gives the payload fit (module docstring).

    Attributes
    ----------
    measured, robot
        ``(N, m)`` channels and the robot model's prediction of them.
    columns
        ``(N, m, 10)`` the link's standard-parameter columns ``Y_k``.
    robot_jacobian
        ``(N, m, r)`` the robot prediction's derivative in its parameters ``θ_b`` (its base regressor).
    segments
        ``(start, stop)`` samples of each segment (records stacked): no lag of the HAC covariance crosses them.
    """

    measured: NDArray[np.float64]
    robot: NDArray[np.float64]
    columns: NDArray[np.float64]
    robot_jacobian: NDArray[np.float64]
    segments: tuple[tuple[int, int], ...] = ()

    @property
    def target(self) -> NDArray[np.float64]:
        return self.measured - self.robot

    @property
    def n_samples(self) -> int:
        return int(self.measured.shape[0])


def _check_joint_columns(model: IdentifiedModel, path: Path) -> None:
    """Refuse a CSV/Parquet record of a robot with more joints than the model's."""
    if not path.is_file() or data_suffix(path) not in (".csv", ".parquet"):
        return
    if data_suffix(path) == ".csv":
        with csv_input(path) as stream:  # a packed CSV file's header, decompressed
            header = pd.read_csv(stream, nrows=0).columns
    else:
        header = pd.read_parquet(path).columns
    n = model.robot.n_joints
    extra = [column for column in header if column in (f"q{n + 1}", f"tau{n + 1}")]
    if extra:
        raise PayloadError(f"{path} holds column {extra[0]!r}: a record of a robot with more joints than the model's "
                           f"{model.robot.name} ({n}); give the model identified on this robot")


def _records(model: IdentifiedModel, data: Any, role: str) -> Measurements:
    """Paths (read as the model's records were) or measurements, prepared as the model's preprocessing says."""
    if isinstance(data, Measurements):
        segments: tuple[Measurements, ...] = (data,)
    elif isinstance(data, (str, Path)):
        data = [data]
        segments = ()
    elif isinstance(data, Sequence) and data and all(isinstance(item, Measurements) for item in data):
        segments = tuple(data)
    else:
        segments = ()
    if not segments:
        if not isinstance(data, Sequence) or not data:
            raise TypeError(f"{role}: give record paths or Measurements")
        paths = [Path(item) for item in data]
        for path in paths:
            _check_joint_columns(model, path)
        segments = model.read(paths)
    for segment in segments:
        if segment.n_joints != model.robot.n_joints:
            raise PayloadError(f"{role} has {segment.n_joints} joints, the model's {model.robot.name} "
                               f"{model.robot.n_joints}: give the model identified on this robot")
    return model.prepare(segments)


def payload_rows(model: IdentifiedModel, data: Any, link: int, *, as_recorded: bool = False,
                 role: str = "the payload records") -> PayloadRows:
    """The rows of ``data`` (paths or :class:`Measurements`) for a payload on link ``link`` (1-based): prepared as
    the model's records were, the motion moved by its delay; ``as_recorded``: against the channels as recorded
    (validation) rather than the preprocessed ones (fit)."""
    prepared = _records(model, data, role)
    if model.file.delay is not None:
        prepared = delayed(prepared, model.file.delay)
    if as_recorded:
        prepared = prepared.as_recorded
    try:
        measured = prepared.channels(model.channels)
    except (KeyError, ValueError) as error:
        raise PayloadError(f"{role} lack the model's channels {list(model.channels)}: {error}") from None
    q, dq, ddq = prepared.q, prepared.dq, prepared.ddq
    segments = tuple((int(piece.start), int(piece.stop)) for piece in segment_slices(prepared))
    return PayloadRows(measured, model.robot_prediction(q, dq, ddq), model.link_columns(link, q, dq, ddq),
                       model.regressor(q, dq, ddq), segments)


# ---------------------------------------------------------------------------------------------- the fit

def _scales(mass: float, com: NDArray[np.float64]) -> NDArray[np.float64]:
    """Mass, mass x length, mass x length² for the ten parameters (length: the centre of mass's distance, at least
    :data:`MIN_LENGTH`)."""
    length = max(float(np.linalg.norm(com)), MIN_LENGTH)
    return np.array([mass] + [mass * length] * 3 + [mass * length ** 2] * 6)


@dataclass(frozen=True)
class _LinearFit:
    """One weighted least-squares pass: the estimate, ``A⁺`` and the structural directions."""

    parameters: NDArray[np.float64]
    information: NDArray[np.float64]
    inverse: NDArray[np.float64]
    structural: NDArray[np.bool_]


def _weighted_fit(rows: PayloadRows, weights: NDArray[np.float64], free: NDArray[np.bool_],
                  fixed: NDArray[np.float64], scales: NDArray[np.float64]) -> _LinearFit:
    """``π`` with ``π[~free] = fixed[~free]``; the free ones by weighted least squares in scaled coordinates."""
    Y = rows.columns
    target = rows.target - Y[:, :, ~free] @ fixed[~free]
    A = np.einsum("nmi,m,nmj->ij", Y, weights, Y, optimize=True)
    b = np.einsum("nmi,m,nm->i", Y, weights, target, optimize=True)
    S = scales[free]
    scaled = A[np.ix_(free, free)] * np.outer(S, S)
    values, vectors = np.linalg.eigh((scaled + scaled.T) / 2)
    kept = values > STRUCTURAL_TOLERANCE * max(values[-1], np.finfo(float).tiny)
    pinv = (vectors[:, kept] / values[kept]) @ vectors[:, kept].T
    parameters = np.array(fixed, dtype=float)
    parameters[free] = S * (pinv @ (S * b[free]))
    inverse = np.zeros((10, 10))
    inverse[np.ix_(free, free)] = pinv * np.outer(S, S)
    structural = np.zeros(10, dtype=bool)
    if not kept.all():
        loading = np.sum(vectors[:, ~kept] ** 2, axis=1)
        structural[np.flatnonzero(free)[loading > 0.5]] = True
    return _LinearFit(parameters, A, inverse, structural)


@functools.lru_cache(maxsize=1)
def _consistent_solver() -> casadi.Function:
    """IPOPT on ``x = (z, ψ)``: ``min ½ (S z − π̂)ᵀ A (S z − π̂)`` s.t. ``S z = θ(ψ)`` (the lifted Cholesky
    factorisation, ``ψ_0..3 ≥ 0`` by bounds); parameters ``(A, π̂, S)``."""
    z, psi = casadi.SX.sym("z", 10), casadi.SX.sym("psi", 10)
    A, estimate, S = casadi.SX.sym("A", 10, 10), casadi.SX.sym("pi_hat", 10), casadi.SX.sym("S", 10)
    difference = S * z - estimate
    theta, _ = link_from_psi(psi)
    nlp = {"x": casadi.vertcat(z, psi), "p": casadi.vertcat(casadi.vec(A), estimate, S),
           "f": 0.5 * casadi.mtimes([difference.T, A, difference]), "g": S * z - theta}
    options = {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes", "max_iter": 500, "tol": 1e-10}}
    return casadi.nlpsol("payload_consistent", "ipopt", nlp, options)


def _consistent(estimate: NDArray[np.float64], information: NDArray[np.float64], scales: NDArray[np.float64],
                mass: float | None) -> NDArray[np.float64]:
    """The consistent body nearest ``estimate`` in the metric ``information`` (module docstring)."""
    start = project_link(estimate if estimate[0] > 0 else np.r_[scales[0], estimate[1:]])
    if mass is not None:
        start = start * (mass / start[0])  # the same body scaled to the known mass: still consistent
    phi = log_cholesky_from_link(start)
    psi0 = np.r_[np.exp(phi[:4]), phi[4:]]
    # the cost in z = π / S has the Hessian S A S: normalise it to a unit largest diagonal
    normalised = information / max(float(np.max(np.abs(np.diag(information) * scales ** 2))), np.finfo(float).tiny)
    lbx, ubx = np.full(20, -np.inf), np.full(20, np.inf)
    lbx[10:14] = 0.0
    if mass is not None:
        lbx[0] = ubx[0] = mass / scales[0]
    solution = _consistent_solver()(x0=np.r_[start / scales, psi0], lbx=lbx, ubx=ubx, lbg=0.0, ubg=0.0,
                                    p=np.r_[normalised.reshape(-1, order="F"), estimate, scales])
    return project_link(np.asarray(solution["x"], dtype=float).reshape(-1)[:10] * scales, floor=1e-9)


# ---------------------------------------------------------------------------------------------- the result

@dataclass(frozen=True)
class PayloadResult:
    """An identified payload (module docstring).

    Attributes
    ----------
    link, link_index
        The joint that moves the payload's link, and the link's 1-based index.
    body
        The consistent estimate with its total covariance (:class:`~estimation.payload.body.PayloadBody`).
    cov_noise, cov_robot
        The two parts of that covariance: the record's noise and the robot model's own uncertainty.
    unconstrained
        The least-squares estimate (equal to ``body.parameters`` unless ``constraint_active``).
    constraint_active
        The least-squares estimate was not a rigid body: the body is the nearest consistent one.
    undetermined
        The standard parameters (``m, mx, …, Izz``) the data did not determine (module docstring).
    mass_known
        The mass was given, not fitted.
    residual_variance
        Channel to the residual variance after the fit (the weights' ``σ_c²``).
    robot_variance
        Channel to the robot model's own channel variance (for comparison).
    n_samples
        Samples fitted.
    validation_before, validation_after
        Channel to MSE on the validation records against the channels as recorded: the robot model alone and with
        the payload (``None`` without validation records).
    """

    link: str
    link_index: int
    body: PayloadBody
    cov_noise: NDArray[np.float64]
    cov_robot: NDArray[np.float64]
    unconstrained: NDArray[np.float64]
    constraint_active: bool
    undetermined: tuple[str, ...]
    mass_known: bool
    residual_variance: Mapping[str, float]
    robot_variance: Mapping[str, float]
    n_samples: int
    validation_before: Mapping[str, float] | None = None
    validation_after: Mapping[str, float] | None = None

    def std_part(self, cov: NDArray[np.float64]) -> dict[str, Any]:
        """``{mass, com, inertia}`` standard deviations of one covariance part."""
        part = PayloadBody(self.body.parameters, cov)
        return part.described(part.values_std)

    def to_dict(self) -> dict[str, Any]:
        """``{"payload": {mass, com, inertia, std, std_parts, std_note, undetermined, link, link_index, mass_known,
        consistent, parameters, cov, principal_moments, residual_variance, robot_variance, n_samples},
        "validation": {"before": {channel: mse}, "after": {…}} | null}``."""
        body = self.body.to_dict()
        payload = {
            "mass": body["mass"], "com": body["com"], "inertia": body["inertia"], "std": body["std"],
            "std_parts": {"record_noise": self.std_part(self.cov_noise), "robot_model": self.std_part(self.cov_robot)},
            "std_note": STD_NOTE, "undetermined": list(self.undetermined),
            "link": self.link, "link_index": self.link_index, "mass_known": self.mass_known,
            "consistent": {"constraint_active": self.constraint_active,
                           "unconstrained": dict(zip(LINK_PARAMETER_NAMES, map(float, self.unconstrained)))},
            "parameters": body["parameters"], "cov": self.body.cov.tolist(),
            "principal_moments": body["principal_moments"],
            "residual_variance": dict(self.residual_variance), "robot_variance": dict(self.robot_variance),
            "n_samples": self.n_samples,
        }
        validation = None if self.validation_before is None else {
            "before": {"mse": dict(self.validation_before), "label": "the robot model alone"},
            "after": {"mse": dict(self.validation_after or {}), "label": "with the payload"}}
        return {"payload": payload, "validation": validation}

    def model_file_entry(self) -> dict[str, Any]:
        """The ``payload`` entry of a model file (:mod:`estimation.identification.model_file`)."""
        return {"link": self.link, "link_index": self.link_index, "parameters": self.body.parameters.tolist(),
                "cov": self.body.cov.tolist(), "names": list(LINK_PARAMETER_NAMES)}

    def model_file_document(self, model: IdentifiedModel) -> dict[str, Any]:
        """``model``'s model file with this payload: what ``oed predict`` and ``oed export`` read. The error it
        reports (``reported.validation_mse``) is the one of the model with the payload on the validation records
        with it (``validation.after``, what ``oed predict`` measures there; ``None`` without them); the
        alternatives' errors, measured without the payload on the robot's own validation record, are dropped
        (``None``)."""
        document = model.file.to_dict()
        document["payload"] = self.model_file_entry()
        document["reported"] = {"validation_mse": None if self.validation_after is None
                                else dict(self.validation_after)}
        document["alternatives"] = {name: {**entry, "validation_mse": None}
                                    for name, entry in document["alternatives"].items()}
        if document.get("consistent") is not None:
            document["consistent"]["validation_mse"] = None
        return document

    def document(self, model: IdentifiedModel) -> dict[str, Any]:
        """The ``payload.json`` of ``oed payload``: :meth:`to_dict` plus ``model_file``, the robot's model with the
        payload (``oed predict --model payload.json`` predicts with both, ``oed export`` adds it to its link)."""
        return {**self.to_dict(), "model_file": self.model_file_document(model)}

    def summary(self) -> str:
        """Lines for a terminal: the body with its standard deviations and what was not determined."""
        body, std = self.body.to_dict(), self.body.to_dict()["std"]
        com = ", ".join(f"{1e3 * v:.2f} ± {1e3 * s:.2f}" for v, s in zip(body["com"], std["com"]))
        inertia = ", ".join(f"{key} {body['inertia'][key]:.4g} ± {std['inertia'][key]:.2g}" for key in body["inertia"])
        lines = [f"payload on link {self.link_index} ({self.link}), {self.n_samples} samples"
                 + (", mass known" if self.mass_known else ""),
                 f"  mass {body['mass']:.5g} ± {std['mass']:.2g} kg", f"  centre of mass [{com}] mm (link frame)",
                 f"  inertia about it (kg m^2): {inertia}",
                 "  ± one standard deviation: the record's noise and the robot model's own uncertainty "
                 f"(mass ± {self.std_part(self.cov_noise)['mass']:.2g} and ± {self.std_part(self.cov_robot)['mass']:.2g})"]
        if self.constraint_active:
            lines.append("  the least-squares estimate was not a rigid body: the nearest consistent body is given")
        if self.undetermined:
            lines.append(f"  not determined by the data: {', '.join(self.undetermined)}")
        return "\n".join(lines)


def _variances(rows: PayloadRows, parameters: NDArray[np.float64], n_fitted: int) -> NDArray[np.float64]:
    residual = rows.target - rows.columns @ parameters
    dof = max(rows.n_samples - n_fitted / max(rows.measured.shape[1], 1), 1.0)
    return np.maximum(np.sum(residual ** 2, axis=0) / dof, np.finfo(float).tiny)


def _mse(measured: NDArray[np.float64], predicted: NDArray[np.float64], channels: Sequence[str]) -> dict[str, float]:
    return dict(zip(channels, map(float, np.mean((measured - predicted) ** 2, axis=0))))


def identify_payload(model: IdentifiedModel, data: Any, *, validate: Any = None, link: str | int | None = None,
                     mass: float | None = None, covariance: CovarianceMethod = "hac") -> PayloadResult:
    """The payload on ``link`` (default the last) from ``data``, ``model`` held fixed (module docstring).

    Parameters
    ----------
    model
        The robot's identified model (:meth:`IdentifiedModel.load` of a ``result.json``/``report.json``).
    data, validate
        Records made with the payload: paths (read and prepared as the model's records were) or
        :class:`~dynamics.measurements.Measurements`; ``validate``: records no choice used, for the error before
        (robot model alone) and after.
    link
        A URDF link name, the joint that moves it, ``link<k>`` or ``k``; ``None``: the last link.
    mass
        The payload's known mass, kg (then the nine other parameters are fitted).
    covariance
        The record-noise part: ``"hac"`` (default; Newey–West, it holds when the residuals are correlated in time,
        e.g. filtered channels, and equals the classical one within sampling error when they are white:
        :mod:`estimation.uncertainty.covariance`) or ``"classical"`` (``A⁺``, white residuals assumed).

    Raises
    ------
    PayloadError
        An unknown link, records of another robot, records without the payload, a model that carries one already.
    """
    if not isinstance(model, IdentifiedModel):
        raise TypeError(f"model must be an IdentifiedModel, got {type(model).__name__}")
    if model.payload_link is not None:
        raise PayloadError("the model file carries a payload already: give the robot's model without it (the "
                           "result.json of `oed identify` or report.json of `oed diagnose`)")
    if mass is not None and not (np.isfinite(mass) and mass > 0):
        raise PayloadError(f"the known mass must be positive, got {mass} kg")
    covariance = check_method(covariance)
    index, name = resolve_link(model, link)
    rows = payload_rows(model, data, index)
    channels = model.channels
    robot_variance = np.asarray(model.file.band_variance, dtype=float)
    free = np.ones(10, dtype=bool)
    fixed = np.zeros(10)
    if mass is not None:
        free[0], fixed[0] = False, float(mass)
    # pass 1: weights of the robot model's noise, scales of a 1 kg body; pass 2: the residuals' noise, the body's
    weights = 1.0 / np.maximum(robot_variance, np.finfo(float).tiny)
    first = _weighted_fit(rows, weights, np.ones(10, dtype=bool), np.zeros(10), _scales(1.0, np.zeros(3)))
    variance = _variances(rows, first.parameters, 10)
    free_fit = _weighted_fit(rows, 1.0 / variance, np.ones(10, dtype=bool), np.zeros(10),
                             _scales(max(abs(first.parameters[0]), 1e-3), np.zeros(3)))
    _check_payload_seen(free_fit, rows, model, mass)
    guess = free_fit.parameters if mass is None else np.r_[mass, free_fit.parameters[1:]]
    guessed_mass = guess[0] if guess[0] > 0 else 1.0
    scales = _scales(guessed_mass, guess[1:4] / guessed_mass)
    fit = _weighted_fit(rows, 1.0 / variance, free, fixed, scales)
    variance = _variances(rows, fit.parameters, int(free.sum()))
    fit = _weighted_fit(rows, 1.0 / variance, free, fixed, scales)
    _check_model_fits(variance, robot_variance, channels, model)

    weights = 1.0 / variance
    cov_noise = fit.inverse
    if covariance == "hac":
        residuals = rows.target - rows.columns @ fit.parameters
        hac, _ = hac_covariance(rows.columns[:, :, free], residuals, weights, fit.inverse[np.ix_(free, free)],
                                segments=rows.segments or None)
        cov_noise = np.zeros((10, 10))
        cov_noise[np.ix_(free, free)] = hac
    sensitivity = fit.inverse @ np.einsum("nmi,m,nmr->ir", rows.columns, weights, rows.robot_jacobian, optimize=True)
    cov_robot = sensitivity @ model.cov @ sensitivity.T
    cov = cov_noise + cov_robot
    parameters = fit.parameters
    constraint_active = not (parameters[0] > 0 and consistency_margin(parameters) > 0)
    if constraint_active:
        parameters = _consistent(fit.parameters, fit.information, scales, mass)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    undetermined = tuple(parameter for parameter, s, scale, structural, is_free
                         in zip(LINK_PARAMETER_NAMES, std, scales, fit.structural, free)
                         if is_free and (structural or s > RELATIVE_STD_THRESHOLD * scale))
    before = after = None
    if validate is not None:
        held_out = payload_rows(model, validate, index, as_recorded=True, role="the validation records")
        before = _mse(held_out.measured, held_out.robot, channels)
        after = _mse(held_out.measured, held_out.robot + held_out.columns @ parameters, channels)
    return PayloadResult(
        link=name, link_index=index, body=PayloadBody(parameters, cov), cov_noise=cov_noise, cov_robot=cov_robot,
        unconstrained=fit.parameters, constraint_active=constraint_active, undetermined=undetermined,
        mass_known=mass is not None, residual_variance=dict(zip(channels, map(float, variance))),
        robot_variance=dict(zip(channels, map(float, robot_variance))), n_samples=rows.n_samples,
        validation_before=before, validation_after=after)


def _check_payload_seen(fit: _LinearFit, rows: PayloadRows, model: IdentifiedModel, mass: float | None) -> None:
    """Refuse records whose free mass estimate is not clearly above zero (with a known mass: when the data could
    have seen it)."""
    std = float(np.sqrt(max(fit.inverse[0, 0], 0.0)))
    estimate = float(fit.parameters[0])
    if fit.structural[0] or (mass is not None and NO_PAYLOAD_SIGMAS * std > mass):
        return  # the data cannot see the mass (or not the one given): nothing to say about it here
    if estimate < NO_PAYLOAD_SIGMAS * std:
        raise PayloadError(f"the records show no payload: its mass estimate {estimate:.3g} ± {std:.2g} kg is not "
                           f"{NO_PAYLOAD_SIGMAS:g} standard deviations above zero; were they recorded with the payload "
                           f"(and is the model the robot's without it)?"
                           + ("" if mass is None else f" (a {mass:g} kg payload was given)"))


def _check_model_fits(variance: NDArray[np.float64], robot_variance: NDArray[np.float64], channels: Sequence[str],
                      model: IdentifiedModel) -> None:
    """Refuse records the robot model plus a payload cannot explain (another robot's model, another set-up)."""
    ratio = variance / np.maximum(robot_variance, np.finfo(float).tiny)
    worst = int(np.argmax(ratio))
    if ratio[worst] > MISMATCH_RATIO:
        raise PayloadError(
            f"the model of {model.robot.name} does not explain these records: after the payload fit the residual "
            f"variance of {channels[worst]} is {ratio[worst]:.3g} times the model's own ({variance[worst]:.3g} against "
            f"{robot_variance[worst]:.3g}); is it this robot's model, in the same set-up (transmission, friction, "
            "units)?")
