"""``oed identify --consistent``: the physically consistent estimate beside the unconstrained one.

``identify_consistent(result, train, validate)`` refits an :class:`estimation.identification.fit.IdentificationResult`
under the log-Cholesky map (:class:`estimation.consistent.least_squares.ConsistentLeastSquares`) with the
unconstrained fit's channel weights, and compares both on the same data: the price of
consistency per channel. Its :meth:`ConsistentResult.to_dict` adds these keys to ``result.json``::

    links: [{name, mass, com, inertia, inertia_com, consistency_margin, std}]   # std: with a prior only
    consistent: {method, uncertainty_method, prior_weight, prior, parameters: [{name, expression, value, std}],
                 effects: {fv1: ..}, active_bounds: [text], excess_chi2, solver: {...},
                 prior_weight_choice: text, prior_weight_search: [{prior_weight, weighted_validation_error}],
                 undetermined: {threshold_relative_std, n_directions, n_undetermined, n_structural,
                                links: {NAME: [parameter]}, directions: [{relative_std, structural, parameters}]},
                 train: {mse}, validation: {mse} | null,
                 price: {train: {channel: mse ratio}, validation: {channel: mse ratio} | null}}

``inertia`` is about the link-frame origin (the standard parameters), ``inertia_com`` about the
centre of mass; ``price`` divides each channel's MSE of the consistent estimate by that of the
unconstrained one (1.0: consistency costs nothing there); ``undetermined`` names the links and
directions of the bodies the data did not determine, where the prior sets the estimate
(:mod:`estimation.consistent.determination`).

Files: a prior (``--prior``) is a JSON document with ``links: [{name, mass, com, inertia}]`` (the
``links`` of an earlier result, say) for the same links; bounds (``--link-bounds``) are
``{"links": {NAME or 1-based index: {"mass": [min, max], "com_lower": [x, y, z], "com_upper": [x, y, z]}}}``.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dynamics.physical_parameters import LinkBounds, link_summary
from dynamics.robot import RobotModel
from estimation.consistent.determination import Determination, determination
from estimation.consistent.least_squares import ConsistentEstimate, ConsistentLeastSquares
from estimation.identification.fit import IdentificationResult
from estimation.estimators.identification_problem import stack
from dynamics.measurements import Measurements
from estimation.identification.validation import Comparison, compare


class PriorMismatchError(ValueError):
    """A prior file that does not describe this robot's links."""


@dataclass(frozen=True)
class ConsistentResult:
    """The consistent estimate with its fit, and how it compares with the unconstrained one."""

    estimate: ConsistentEstimate
    unconstrained: IdentificationResult
    train: Comparison
    validation: Comparison | None
    prior_source: str
    #: the weights tried by ``--prior-weight auto`` and their channel-weighted validation errors (else empty)
    prior_weight_search: tuple[dict[str, float], ...] = ()
    #: the links and directions of the bodies the data did not determine (``None``: not assessed)
    determination: Determination | None = None
    #: how the prior's weight was chosen: ``given``, ``held-out`` (``--prior-weight auto``) or ``default``
    prior_weight_choice: str = "given"

    def to_dict(self) -> dict[str, Any]:
        """The keys ``links`` and ``consistent`` of ``result.json`` (module docstring)."""
        estimate = self.estimate
        links = []
        for k, (name, theta) in enumerate(zip(estimate.link_names, estimate.link_parameters())):
            std = None if estimate.theta_std is None else estimate.theta_std[10 * k : 10 * (k + 1)].tolist()
            links.append({"name": name, **link_summary(theta), "consistency_margin": float(estimate.margins[k]),
                          "std": std})
        return {
            "links": links,
            "consistent": {
                "method": f"{self.unconstrained.estimate.method} under the log-Cholesky map (IPOPT)",
                "uncertainty_method": estimate.uncertainty_method,
                "prior_weight": estimate.prior_weight,
                "prior": self.prior_source if estimate.prior_weight > 0 else None,
                "prior_weight_choice": self.prior_weight_choice,
                **({"prior_weight_search": [dict(entry) for entry in self.prior_weight_search]}
                   if self.prior_weight_search else {}),
                "undetermined": None if self.determination is None else self.determination.to_dict(),
                "parameters": estimate.records(),
                "effects": estimate.effect_values(),
                "active_bounds": list(estimate.active_bounds),
                "excess_chi2": estimate.excess_chi2,
                "solver": estimate.solver,
                "train": {"mse": self.train.mse},
                "validation": None if self.validation is None else {"mse": self.validation.mse},
                "price": {
                    "train": _ratio(self.train.mse, self.unconstrained.train.mse),
                    "validation": None if self.validation is None or self.unconstrained.validation is None
                    else _ratio(self.validation.mse, self.unconstrained.validation.mse),
                },
            },
        }

    def robot(self) -> RobotModel:
        """The robot carrying the consistent links (for the simulator and the controllers)."""
        return self.unconstrained.model.robot.with_parameters(self.estimate.theta[: 10 * len(self.estimate.link_names)])


def identify_consistent(
    result: IdentificationResult,
    train: Measurements,
    validate: Measurements | None = None,
    *,
    prior_weight: float = 0.0,
    prior: NDArray[np.float64] | None = None,
    prior_source: str = "robot description",
    bounds: Mapping[str, LinkBounds] | None = None,
    starts: int = 2,
) -> ConsistentResult:
    """Consistent refit of ``result`` (its model, train data and channel weights), with what its data did
    not determine of the bodies (:func:`estimation.consistent.determination.determination`, in units of the
    prior's bodies: ``prior``, else the robot description's)."""
    if getattr(result, "shaped_fit", None) is not None:
        raise ValueError("the consistent refit works on the linear effects: this result has laws with shape parameters "
                         "(coulomb:tanh, sigmoid…), fitted by variable projection; declare their plain forms")
    model = result.model
    estimator = ConsistentLeastSquares(prior_weight=prior_weight, prior=prior, bounds=bounds, starts=starts)
    estimate = estimator.fit(model, stack(model, train), unconstrained=result.estimate).estimate_
    train_comparison = compare(model, estimate.values, train, label="identification (consistent)")
    validation = None if validate is None else compare(model, estimate.values, validate, label="validation (consistent)")
    nominal = model.robot.standard_parameters if prior is None else np.asarray(prior, dtype=float).reshape(-1)
    return ConsistentResult(estimate, result, train_comparison, validation, prior_source,
                            determination=determination(model, result.estimate.cov, nominal))


def _ratio(numerator: dict[str, float], denominator: dict[str, float]) -> dict[str, float | None]:
    return {channel: (numerator[channel] / value if value > 0 else None) for channel, value in denominator.items()}


def _read_json(path: str | Path, what: str) -> Any:
    path = Path(path)
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{what} file not found: {path}") from None
    except json.JSONDecodeError as error:
        raise ValueError(f"{what} file {path} is not JSON: {error}") from None


def load_prior(path: str | Path, robot: RobotModel) -> NDArray[np.float64]:
    """The ``10 n`` link parameters of a prior file (``links: [{name, mass, com, inertia}]``),
    checked against ``robot``'s links (count and names)."""
    document = _read_json(path, "prior")
    links = document.get("links") if isinstance(document, dict) else None
    if not isinstance(links, list) or not all(isinstance(link, dict) for link in links):
        raise PriorMismatchError(f"prior file {path}: expected an object with links: [{{name, mass, com, inertia}}]")
    names = [link.get("name") for link in links]
    if names != robot.joint_names:
        source = f" (robot {document.get('robot')!r})" if document.get("robot") else ""
        raise PriorMismatchError(
            f"prior file {path}{source} describes links {names}, not this robot's {robot.joint_names} "
            f"({robot.name!r}): a prior for another robot")
    theta = []
    for link in links:
        try:
            mass = float(link["mass"])
            com = np.asarray(link["com"], dtype=float).reshape(3)
            inertia = np.asarray(link["inertia"], dtype=float).reshape(3, 3)
        except (KeyError, TypeError, ValueError):
            raise PriorMismatchError(f"prior file {path}: link {link.get('name')!r} needs mass, com [3] and "
                                     "inertia [3x3] (about the link-frame origin)") from None
        if not (np.isfinite(mass) and np.all(np.isfinite(com)) and np.all(np.isfinite(inertia))):
            raise PriorMismatchError(f"prior file {path}: link {link.get('name')!r} holds NaN or inf")
        theta.append([mass, *(mass * com), inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2],
                      inertia[1, 2], inertia[2, 2]])
    return np.concatenate(theta)


def load_link_bounds(path: str | Path, robot: RobotModel) -> dict[str, LinkBounds]:
    """Bounds by link name from a JSON file (module docstring); links by name or 1-based index."""
    document = _read_json(path, "link bounds")
    links = document.get("links") if isinstance(document, dict) else None
    if not isinstance(links, dict):
        raise ValueError(f"link bounds file {path}: expected {{\"links\": {{NAME: {{mass, com_lower, com_upper}}}}}}")
    bounds = {}
    for key, entry in links.items():
        name = key
        if key not in robot.joint_names:
            if key.isdigit() and 1 <= int(key) <= robot.n_joints:
                name = robot.joint_names[int(key) - 1]
            else:
                raise ValueError(f"link bounds file {path}: unknown link {key!r}; the links are {robot.joint_names} "
                                 f"(or 1..{robot.n_joints})")
        if not isinstance(entry, dict) or set(entry) - {"mass", "com_lower", "com_upper"}:
            raise ValueError(f"link bounds file {path}: link {key!r} takes mass, com_lower, com_upper only")
        values = {}
        for field, value in entry.items():
            if not isinstance(value, list):
                raise ValueError(f"link bounds file {path}: link {key!r} {field} must be a list")
            if field == "mass":  # null: no bound
                value = [0.0 if value and value[0] is None else value[0], *[np.inf if v is None else v for v in value[1:]]]
            else:
                missing = -np.inf if field == "com_lower" else np.inf
                value = [missing if v is None else v for v in value]
            values[field] = value
        bounds[name] = LinkBounds(**values)
    return bounds
