"""``--consistent`` of ``oed identify``: the checks of its options, the refit and the choice of the prior's weight
(:data:`PRIOR_WEIGHT_GRID`, :data:`PRIOR_WEIGHT_TOLERANCE`, :data:`DEFAULT_PRIOR_WEIGHT`), and its summary lines."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from estimation.consistent.identification import ConsistentResult, identify_consistent, load_link_bounds, load_prior


#: the prior weights ``--prior-weight auto`` tries
PRIOR_WEIGHT_GRID = (0.0, 0.1, 1.0, 10.0, 100.0)
#: ``--prior-weight auto`` takes the largest weight whose validation error is within this fraction of the best
PRIOR_WEIGHT_TOLERANCE = 0.01
#: the prior's weight without ``--validate`` to choose it: one unit of ½χ², where the prior weighs about as much as
#: the data on a direction of the bodies known to its own size (estimation.consistent.determination); the data
#: decide every direction they determine better than that
DEFAULT_PRIOR_WEIGHT = 1.0


def check_consistent_arguments(args: Any) -> None:
    """Refuse consistency options without ``--consistent`` and a negative or non-finite weight."""
    if not args.consistent:
        given = [flag for flag, value in (("--prior-weight", args.prior_weight is not None), ("--prior", args.prior),
                                          ("--link-bounds", args.link_bounds)) if value]
        if given:
            raise ValueError(f"{', '.join(given)} only with --consistent")
    if args.prior_weight == "auto":
        if not getattr(args, "validate", None):
            raise ValueError("--prior-weight auto chooses the weight by the validation error: give --validate")
        return
    if args.prior_weight is not None and not (np.isfinite(args.prior_weight) and args.prior_weight >= 0):
        raise ValueError(f"--prior-weight must be a finite non-negative number, got {args.prior_weight}")


def consistent_refit(args: Any, result, train, validation) -> ConsistentResult | None:
    """The consistent refit of ``result`` (``None`` without ``consistent``), its prior weight given or chosen."""
    if not args.consistent:
        return None
    robot = result.model.robot
    prior = None if args.prior is None else load_prior(args.prior, robot)
    bounds = None if args.link_bounds is None else load_link_bounds(args.link_bounds, robot)

    def refit(weight: float) -> ConsistentResult:
        return identify_consistent(result, train, validation, prior_weight=weight, prior=prior,
                                   prior_source=args.prior or "robot description", bounds=bounds)

    weight, choice = prior_weight_choice(args.prior_weight, validation is not None)
    if weight != "auto":
        return dataclasses.replace(refit(weight), prior_weight_choice=choice)
    return dataclasses.replace(choose_prior_weight(refit, result), prior_weight_choice=choice)


def prior_weight_choice(given: float | str | None, validated: bool) -> tuple[float | str, str]:
    """``(weight, how)``: the weight given, else ``auto`` with a validation record, else
    :data:`DEFAULT_PRIOR_WEIGHT`; ``how`` is ``given``, ``held-out`` or ``default``."""
    if given is None:
        return ("auto", "held-out") if validated else (DEFAULT_PRIOR_WEIGHT, "default")
    return given, "held-out" if given == "auto" else "given"


def choose_prior_weight(refit, result) -> ConsistentResult:
    """The consistent fit of the largest weight of :data:`PRIOR_WEIGHT_GRID` whose channel-weighted validation
    error is within :data:`PRIOR_WEIGHT_TOLERANCE` of the best: where the data do not determine a body, the
    prior (the description's by default) does, as far as the held-out record allows. The search is kept in
    the result (``prior_weight_search``)."""
    weights = result.estimate.weights if result.estimate.method == "wls" else 1.0 / result.estimate.channel_variance
    fits, errors = [], []
    for weight in PRIOR_WEIGHT_GRID:
        fit = refit(weight)
        fits.append(fit)
        errors.append(float(sum(w * fit.validation.mse[c] for w, c in zip(weights, result.model.channels))))
    best = min(errors)
    chosen = max(index for index, error in enumerate(errors) if error <= (1 + PRIOR_WEIGHT_TOLERANCE) * best)
    search = tuple({"prior_weight": weight, "weighted_validation_error": error}
                   for weight, error in zip(PRIOR_WEIGHT_GRID, errors))
    return dataclasses.replace(fits[chosen], prior_weight_search=search)


def consistent_lines(consistent: ConsistentResult | None) -> list[str]:
    """The summary lines of the consistent refit (none without one)."""
    if consistent is None:
        return []
    lines = []
    estimate = consistent.estimate
    how = {"held-out": "chosen by the validation error", "given": "given",
           "default": "the default without --validate to choose it"}[consistent.prior_weight_choice]
    lines.append(f"consistent (prior weight {estimate.prior_weight:g}: {how}; {estimate.solver['status']}, "
          f"{estimate.solver['time_s']:.2f} s): excess chi2 {estimate.excess_chi2:.4g}; active: "
          + (", ".join(estimate.active_bounds) or "none"))
    for name, theta, margin in zip(estimate.link_names, estimate.link_parameters(), estimate.margins):
        com = theta[1:4] / theta[0]
        lines.append(f"  {name}: mass {theta[0]:.4g} kg, com [{com[0]:+.4f} {com[1]:+.4f} {com[2]:+.4f}] m, margin {margin:.2g}")
    if consistent.determination is not None:
        for line in consistent.determination.lines():
            lines.append(line)
    for label, comparison in (("train", consistent.train), ("validation", consistent.validation)):
        if comparison is not None:
            lines.append(f"consistent {label} MSE: " + "  ".join(f"{c} {v:.4g}" for c, v in comparison.mse.items()))
    return lines
