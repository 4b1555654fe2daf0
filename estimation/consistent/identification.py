"""``oed identify --consistent``: the physically consistent estimate beside the unconstrained one.

``consistent_fit(result, train, validate)`` refits an :class:`estimation.identification.fit.IdentificationResult`
(its shaped laws and delay held at their fitted values, :mod:`estimation.consistent.fixed_shapes`; the prior's
weight chosen on ``validate``; :func:`identify_consistent` at one weight, :func:`consistent_refit` a diagnosis's
adopted model, :func:`consistent_refit_file` the model of a ``result.json``/``report.json``) under the log-Cholesky map (:class:`estimation.consistent.least_squares.ConsistentLeastSquares`) with the
unconstrained fit's channel weights, and compares both on the same data: the price of
consistency per channel. Its :meth:`ConsistentResult.to_dict` adds these keys to ``result.json``::

    links: [{name, mass, com, inertia, inertia_com, consistency_margin, std}]   # std: with a prior only
    consistent: {method, uncertainty_method, prior_weight, prior, effect_prior (when used), parameters: [{name, expression, value, std}],
                 effects: {fv1: ..}, active_bounds: [text], excess_chi2, solver: {...},
                 [shape: {vc1: ..}, delay: s | null, shapes_held: text]   # shaped laws or a delay, held fixed
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

import dataclasses
import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from dynamics.physical_parameters import LinkBounds, link_summary
from dynamics.robot import RobotModel
from estimation.consistent.determination import Determination, determination
from estimation.consistent.fixed_shapes import (
    comparisons,
    fixed_comparison,
    fixed_problem,
    fixed_regressor,
    has_fixed_effects,
)
from estimation.data.segments import concatenate
from estimation.consistent.least_squares import ConsistentEstimate, ConsistentLeastSquares
from estimation.identification.fit import IMPLAUSIBLE_CAUSE, IdentificationResult, identify, implausible_records
from estimation.identification.identified_model import IdentifiedModel
from estimation.estimators.identification_problem import stack
from estimation.estimators.least_squares import channel_gram
from dynamics.measurements import Measurements
from estimation.identification.validation import ChannelErrors, Comparison, compare
from estimation.estimators.normal_equations import NormalEquations


#: the prior weights ``prior_weight="auto"`` tries
PRIOR_WEIGHT_GRID = (0.0, 0.1, 1.0, 10.0, 100.0)
#: ``prior_weight="auto"`` takes the largest weight whose validation error is within this fraction of the best
PRIOR_WEIGHT_TOLERANCE = 0.01
#: the prior's weight without a validation record to choose it: one unit of ½χ², where the prior weighs about as
#: much as the data on a direction of the bodies known to its own size (estimation.consistent.determination); the
#: data decide every direction they determine better than that
DEFAULT_PRIOR_WEIGHT = 1.0

PriorWeightChoice = Literal["given", "held-out", "default"]


class PriorMismatchError(ValueError):
    """A prior file that does not describe this robot's links."""


@dataclass(frozen=True)
class ConsistentResult:
    """The consistent estimate with its fit, and how it compares with the unconstrained one."""

    estimate: ConsistentEstimate
    unconstrained: IdentificationResult
    #: the errors on the training and validation records (:class:`~estimation.identification.validation.ChannelErrors`
    #: when fitted from sums: :func:`consistent_fit_sums`)
    train: Comparison | ChannelErrors
    validation: Comparison | ChannelErrors | None
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
                **({"effect_prior": dict(estimate.effect_prior)} if estimate.effect_prior else {}),
                "prior_weight_choice": self.prior_weight_choice,
                **({"prior_weight_search": [dict(entry) for entry in self.prior_weight_search]}
                   if self.prior_weight_search else {}),
                "undetermined": None if self.determination is None else self.determination.to_dict(),
                "parameters": estimate.records(),
                "effects": estimate.effect_values(),
                **self._fixed_effects(),
                "active_bounds": list(estimate.active_bounds),
                "excess_chi2": estimate.excess_chi2,
                "solver": estimate.solver,
                "train": {"mse": self.train.mse},
                "validation": None if self.validation is None else {"mse": self.validation.mse},
                "price": {
                    "train": None if self.train.mse is None or self.unconstrained.train.mse is None
                    else _ratio(self.train.mse, self.unconstrained.train.mse),
                    "validation": None if self.validation is None or self.unconstrained.validation is None
                    or self.validation.mse is None or self.unconstrained.validation.mse is None else _ratio(self.validation.mse, self.unconstrained.validation.mse),
                },
            },
        }

    @property
    def warnings(self) -> tuple[str, ...]:
        """The consistent model's own warnings: each friction or armature parameter the unconstrained fit it was
        refitted from puts implausibly far below zero
        (:func:`~estimation.identification.fit.implausible_records`), held at or above zero here: its value here
        and the unconstrained one, which says the model lacks something (as the unconstrained fit's warning)."""
        values = dict(zip(self.estimate.names, np.asarray(self.estimate.values, dtype=float)))
        method = self.unconstrained.estimate.method
        return tuple(
            f"{record['name']} = {values[record['name']]:.4g} held >= 0 by the physically consistent fit, where the "
            f"unconstrained {method} fit puts it at {record['value']:.4g} ± {record['std']:.2g} "
            f"({-record['value'] / record['std']:.0f} standard deviations below zero), which no {effect} can be: "
            f"{IMPLAUSIBLE_CAUSE}"
            for record, effect in implausible_records(self.unconstrained.model, self.unconstrained.estimate)
            if record["name"] in values)

    def _fixed_effects(self) -> dict[str, Any]:
        """``shape`` (the shaped laws' shapes) and ``delay`` (s) the refit held at the unconstrained fit's values."""
        result = self.unconstrained
        if not has_fixed_effects(result):
            return {}
        shapes = {value.name: float(value.value) for value in result.shapes if value.name != "delay"}
        return {"shape": shapes, "delay": None if result.delay is None else float(result.delay.value),
                "shapes_held": "at the unconstrained fit's values (estimation.consistent.fixed_shapes)"}

    def predict(self, measurements: Measurements) -> NDArray[np.float64]:
        """``(N, m)`` the consistent estimate's channels along ``measurements`` (at the unconstrained fit's
        shapes, along the motion moved by its delay, if any)."""
        return fixed_regressor(self.unconstrained, measurements) @ self.estimate.values

    def compare(self, measurements: Measurements, *, label: str = "consistent") -> Comparison:
        """The consistent estimate along another record (a test record, say) against its channels as recorded,
        as ``train`` and ``validation`` are."""
        if has_fixed_effects(self.unconstrained):
            return fixed_comparison(self.unconstrained, self.estimate.values, measurements, label=label)
        return compare(self.unconstrained.model, self.estimate.values, measurements, label=label)

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
    warm_start: NDArray[np.float64] | None = None,
    undetermined: bool = True,
) -> ConsistentResult:
    """Consistent refit of ``result`` (its model, train data and channel weights) at one prior weight, with what
    its data did not determine of the bodies (:func:`estimation.consistent.determination.determination`, in units
    of the prior's bodies: ``prior``, else the robot description's).

    ``result`` may hold shaped laws and a delay (``identify(..., delay=DelayBounds())``, the diagnosis's
    adopted model): they are held at its fitted values (:mod:`estimation.consistent.fixed_shapes`).
    :func:`consistent_fit` also chooses the prior's weight. ``warm_start``: log-Cholesky coordinates to start from
    first (:class:`estimation.consistent.least_squares.ConsistentLeastSquares`). ``undetermined=False`` leaves the
    determination out (``None``; it does not depend on the weight: :func:`consistent_fit` assesses it once)."""
    model = result.model
    estimator = ConsistentLeastSquares(prior_weight=prior_weight, prior=prior, bounds=bounds, starts=starts,
                                       warm_start=warm_start)
    if has_fixed_effects(result):
        estimate = estimator.fit(model, fixed_problem(result, train), unconstrained=result.estimate).estimate_
        train_comparison = fixed_comparison(result, estimate.values, train, label="identification (consistent)")
        validation = None if validate is None else fixed_comparison(result, estimate.values, validate,
                                                                    label="validation (consistent)")
    else:
        estimate = estimator.fit(model, stack(model, train), unconstrained=result.estimate).estimate_
        train_comparison = compare(model, estimate.values, train, label="identification (consistent)")
        validation = None if validate is None else compare(model, estimate.values, validate,
                                                           label="validation (consistent)")
    return ConsistentResult(estimate, result, train_comparison, validation, prior_source,
                            determination=_determination(result, prior) if undetermined else None)


def _determination(result: IdentificationResult, prior: NDArray[np.float64] | None) -> Determination:
    """What the data of ``result`` did not determine of the bodies, in units of the prior's (the description's)."""
    model = result.model
    nominal = model.robot.standard_parameters if prior is None else np.asarray(prior, dtype=float).reshape(-1)
    return determination(model, result.estimate.cov, nominal)


def prior_weight_choice(given: float | str | None, validated: bool) -> tuple[float | str, PriorWeightChoice]:
    """``(weight, how)``: the weight given, else ``auto`` with a validation record, else
    :data:`DEFAULT_PRIOR_WEIGHT`; ``how`` is ``given``, ``held-out`` or ``default``."""
    if given is None:
        return ("auto", "held-out") if validated else (DEFAULT_PRIOR_WEIGHT, "default")
    if isinstance(given, str):
        if given.strip().lower() != "auto":
            raise ValueError(f"prior_weight must be a number, 'auto' or None, got {given!r}")
        if not validated:
            raise ValueError("prior_weight 'auto' chooses the weight by the validation error: give a validation record")
        return "auto", "held-out"
    return float(given), "given"


def choose_prior_weight(refit: Callable[[float, NDArray[np.float64] | None], ConsistentResult],
                        result: IdentificationResult) -> ConsistentResult:
    """The consistent fit of the largest weight of :data:`PRIOR_WEIGHT_GRID` whose channel-weighted validation
    error is within :data:`PRIOR_WEIGHT_TOLERANCE` of the best: where the data do not determine a body, the
    prior (the description's by default) does, as far as the held-out record allows. The search is kept in
    the result (``prior_weight_search``). ``refit(weight, warm_start)`` is the fit at one weight, with a validation
    record, started first from ``warm_start`` (log-Cholesky coordinates, or ``None``).

    The weights above zero are fitted from the largest down, each started from the optimum of the one before (a
    homotopy along the grid, the path an interior-point method follows as its barrier weight falls): with a prior
    the cost is convex in the pseudo-inertias and strictly inside the cone, so a warm start the certificate
    passes is the optimum the cold starts reach (to IPOPT's tolerance) in a fraction of the iterations, and one
    it does not pass is followed by the cold starts. Weight zero (no prior: the optimum on the cone's boundary,
    where cold starts stop at different points) continues the path from the optimum at the smallest weight down to
    the vanishing pull of ``regularisation`` (:meth:`~estimation.consistent.least_squares.ConsistentLeastSquares.
    _regularised_path`): one certified answer whatever the start."""
    return chosen_prior_weight(prior_weight_path(refit), result)


def prior_weight_path(refit: Callable[[float, NDArray[np.float64] | None], ConsistentResult]
                      ) -> dict[float, ConsistentResult]:
    """The consistent fits at every weight of :data:`PRIOR_WEIGHT_GRID`, from the largest down, each started from
    the optimum of the one before (:func:`choose_prior_weight`), by weight."""
    fits: dict[float, ConsistentResult] = {}
    warm = None
    for weight in sorted(PRIOR_WEIGHT_GRID, reverse=True):
        fits[weight] = refit(weight, warm)
        warm = fits[weight].estimate.phi
    return fits


def chosen_prior_weight(fits: Mapping[float, ConsistentResult], result: IdentificationResult) -> ConsistentResult:
    """Of the fits at every weight of :data:`PRIOR_WEIGHT_GRID` (each with its validation error), the one of the
    largest weight whose channel-weighted validation error is within :data:`PRIOR_WEIGHT_TOLERANCE` of the best
    (:func:`choose_prior_weight`), with the search."""
    if any(fits[weight].validation is None or fits[weight].validation.mse is None for weight in PRIOR_WEIGHT_GRID):
        raise ValueError("choosing the prior's weight needs a validation record")
    chosen, search = _chosen_weight({weight: fit.validation for weight, fit in fits.items()}, result)
    return dataclasses.replace(fits[chosen], prior_weight_search=search)


def _chosen_weight(validations: Mapping[float, Comparison],
                   result: IdentificationResult) -> tuple[float, tuple[dict[str, float], ...]]:
    """The weight :func:`choose_prior_weight` chooses from each weight's comparison on the validation record, and
    the search as kept in the result."""
    weights = result.estimate.weights if result.estimate.method == "wls" else 1.0 / result.estimate.channel_variance
    errors = [float(sum(w * validations[weight].mse[c] for w, c in zip(weights, result.model.channels)))
              for weight in PRIOR_WEIGHT_GRID]
    best = min(errors)
    chosen = max(index for index, error in enumerate(errors) if error <= (1 + PRIOR_WEIGHT_TOLERANCE) * best)
    search = tuple({"prior_weight": weight, "weighted_validation_error": error}
                   for weight, error in zip(PRIOR_WEIGHT_GRID, errors))
    return PRIOR_WEIGHT_GRID[chosen], search


def _searched_fit(result: IdentificationResult, train: Measurements, validate: Measurements, *,
                  prior: NDArray[np.float64] | None, prior_source: str, bounds: Mapping[str, LinkBounds] | None,
                  starts: int) -> ConsistentResult:
    """:func:`choose_prior_weight` over :func:`identify_consistent` at each weight, the same fits and comparisons
    with each regressor evaluated once: the training problem for every weight of the homotopy, then each
    record's regressor for the estimates it compares (every weight's on the validation record, the chosen one's on
    the training record), held one at a time."""
    problem = fixed_problem(result, train) if has_fixed_effects(result) else stack(result.model, train)
    estimates: dict[float, ConsistentEstimate] = {}
    warm = None
    gram, _ = channel_gram(problem)  # the same problem at every weight: its Gram matrices formed once
    for weight in sorted(PRIOR_WEIGHT_GRID, reverse=True):
        estimator = ConsistentLeastSquares(prior_weight=weight, prior=prior, bounds=bounds, starts=starts,
                                           warm_start=warm)
        estimates[weight] = estimator.fit(result.model, problem, unconstrained=result.estimate, gram=gram).estimate_
        warm = estimates[weight].phi
    # the training problem's regressor is the one along ``train`` when ``train`` is one record (stack and
    # fixed_problem evaluate it on concatenate(train), ``train`` itself then)
    same = concatenate(train) is train
    regressor, problem = (problem.Y if same else None), None
    validations = dict(zip(PRIOR_WEIGHT_GRID, comparisons(result, [estimates[w].values for w in PRIOR_WEIGHT_GRID],
                                                          validate, label="validation (consistent)")))
    chosen, search = _chosen_weight(validations, result)
    (train_comparison,) = comparisons(result, [estimates[chosen].values], train,
                                      label="identification (consistent)", regressor=regressor)
    return ConsistentResult(estimates[chosen], result, train_comparison, validations[chosen], prior_source,
                            prior_weight_search=search)


def consistent_fit(
    result: IdentificationResult,
    train: Measurements,
    validate: Measurements | None = None,
    *,
    prior_weight: float | str | None = None,
    prior: NDArray[np.float64] | None = None,
    prior_source: str = "robot description",
    bounds: Mapping[str, LinkBounds] | None = None,
    starts: int = 2,
) -> ConsistentResult:
    """The physically consistent refit of ``result`` with the prior's weight chosen: ``None`` (default) is
    ``"auto"`` with ``validate`` (the largest of :data:`PRIOR_WEIGHT_GRID` whose validation error is within
    :data:`PRIOR_WEIGHT_TOLERANCE` of the best), else :data:`DEFAULT_PRIOR_WEIGHT`; a number is used as given.

    ``result`` holds the model with its effects, shaped laws and delay included (held at its fitted values,
    :mod:`estimation.consistent.fixed_shapes`); ``train``/``validate`` are the records it was fitted and
    validated on (prepared: ``dq``, ``ddq``). ``prior``: ``10 n`` link parameters (default the robot
    description's bodies); ``bounds``: :class:`dynamics.physical_parameters.LinkBounds` by link name.
    """
    weight, how = prior_weight_choice(prior_weight, validate is not None)

    def refit(value: float, warm_start: NDArray[np.float64] | None = None) -> ConsistentResult:
        return identify_consistent(result, train, validate, prior_weight=value, prior=prior,
                                   prior_source=prior_source, bounds=bounds, starts=starts, warm_start=warm_start,
                                   undetermined=False)

    if weight == "auto" and validate is not None:
        fit = _searched_fit(result, train, validate, prior=prior, prior_source=prior_source, bounds=bounds,
                            starts=starts)
    else:
        fit = refit(float(weight))
    return dataclasses.replace(fit, prior_weight_choice=how, determination=_determination(result, prior))


#: scores parameter vectors on the validation record, all in one pass: ``{key: θ_b}`` to ``{key: ChannelErrors}``
Scorer = Callable[[Mapping[Any, NDArray[np.float64]]], Mapping[Any, ChannelErrors]]


def consistent_fit_sums(
    result: IdentificationResult,
    sums: NormalEquations,
    train_errors: Callable[[NDArray[np.float64]], ChannelErrors],
    score: Scorer | None = None,
    *,
    prior_weight: float | str | None = None,
    prior: NDArray[np.float64] | None = None,
    prior_source: str = "robot description",
    bounds: Mapping[str, LinkBounds] | None = None,
    starts: int = 2,
    shapes_fixed: bool = False,
) -> ConsistentResult:
    """:func:`consistent_fit` of a fit from sums (the streamed path: ``result``'s estimate solved from ``sums``, the
    training record's :class:`~estimation.estimators.normal_equations.NormalEquations`): the cost needs the
    per-channel Gram matrices only (:class:`~estimation.consistent.least_squares.ConsistentLeastSquares`), the errors
    are had from the sums (``train_errors(θ_b)``) and from ``score`` (the validation record's errors of several
    parameter vectors, in one pass over its blocks: every weight of the prior's search scored at once, on the same
    samples; ``None``: no validation record). The prior's weight is chosen as :func:`consistent_fit` chooses it, by
    the same rule (:func:`chosen_prior_weight`) along the same path (:func:`prior_weight_path`). ``shapes_fixed``:
    the sums hold ``result``'s shaped laws at its fitted shapes (:mod:`estimation.streaming.diagnosis_selection`)."""
    weight, how = prior_weight_choice(prior_weight, score is not None)

    def refit(value: float, warm_start: NDArray[np.float64] | None = None) -> ConsistentResult:
        estimator = ConsistentLeastSquares(prior_weight=value, prior=prior, bounds=bounds, starts=starts,
                                           warm_start=warm_start)
        estimate = estimator.fit(result.model, sums, unconstrained=result.estimate,
                                 shapes_fixed=shapes_fixed).estimate_
        return ConsistentResult(estimate, result, train_errors(estimate.values), None, prior_source)

    fits = prior_weight_path(refit) if weight == "auto" else {float(weight): refit(float(weight))}
    if score is not None:
        scored = score({key: fit.estimate.values for key, fit in fits.items()})
        fits = {key: dataclasses.replace(fit, validation=scored[key]) for key, fit in fits.items()}
    fit = chosen_prior_weight(fits, result) if weight == "auto" else fits[float(weight)]
    return dataclasses.replace(fit, prior_weight_choice=how, determination=_determination(result, prior))


def consistent_refit(diagnosis: Any, train: Measurements, validate: Measurements | None = None,
                     **settings: Any) -> ConsistentResult:
    """The consistent refit of a diagnosis's adopted model (:class:`estimation.diagnosis.results.Diagnosis`:
    its ``after``, with the effects it adopted, their fitted shapes and the delay), on the records it was
    diagnosed with; ``settings`` as :func:`consistent_fit` (the prior's weight chosen on ``validate``)."""
    after = getattr(diagnosis, "after", diagnosis)
    if not isinstance(after, IdentificationResult):
        raise TypeError(f"expected a diagnosis (with .after) or an IdentificationResult, got {type(diagnosis).__name__}")
    return consistent_fit(after, train, validate, **settings)


def consistent_refit_file(model: str | Path | IdentifiedModel, train: Measurements | Sequence[str | Path],
                          validate: Measurements | Sequence[str | Path] | None = None,
                          **settings: Any) -> ConsistentResult:
    """The consistent refit of the model of a ``result.json``/``report.json`` (``model``: its path or the
    :class:`estimation.identification.identified_model.IdentifiedModel`), on its training and validation records
    (files, read and prepared as the model file says, or prepared measurements).

    The model is rebuilt from its effects, its shaped laws held at the file's shapes and its motion moved by the
    file's delay; its linear coefficients are estimated again on ``train`` (those of the file when ``train`` is the
    record it was identified on) and refitted consistently by :func:`consistent_fit` (``settings``)."""
    identified = model if isinstance(model, IdentifiedModel) else IdentifiedModel.load(model)

    def prepared(records: Measurements | Sequence[str | Path]) -> Measurements:
        if isinstance(records, Measurements):
            return records
        if isinstance(records, (str, Path)):
            records = [records]
        return identified.prepare(identified.read(list(records)))

    train = prepared(train)
    validate = None if validate is None else prepared(validate)
    shapes = {name: float(value) for name, value in identified.file.shape.items()}
    result = identify(identified.model, train, validate, weighted=identified.file.method != "ols",
                      shape_starts=shapes or None, shape_search=False, delay=identified.file.delay)
    return consistent_fit(result, train, validate, **settings)


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
