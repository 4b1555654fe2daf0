"""``oed identify --consistent``: options, the refit and its summary (kept apart from identify.py)."""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from estimation.consistent.identification import ConsistentResult, identify_consistent, load_link_bounds, load_prior


def add_consistent_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("physical consistency")
    group.add_argument("--consistent", action="store_true",
                       help="also fit every link as a real rigid body and friction/armature >= 0 (log-Cholesky map, "
                            "IPOPT); adds links and consistent to the result")
    group.add_argument("--prior-weight", type=prior_weight, default=None, metavar="W",
                       help="with --consistent: weight of the log-det prior towards the nominal bodies (URDF/DH, or "
                            "--prior), in units of half a chi-square (0: none); 'auto': the largest of "
                            f"{', '.join(map(str, PRIOR_WEIGHT_GRID))} whose validation error is within "
                            f"{100 * PRIOR_WEIGHT_TOLERANCE:g} %% of the best (needs --validate). Default: auto with "
                            f"--validate, else {DEFAULT_PRIOR_WEIGHT:g} (the prior sets only what the data do not)")
    group.add_argument("--prior", type=str, help="with --consistent: JSON with links [{name, mass, com, inertia}] "
                                                 "(e.g. an earlier result) as the prior instead of the robot's")
    group.add_argument("--link-bounds", type=str,
                       help='with --consistent: JSON {"links": {NAME or index: {"mass": [min, max], '
                            '"com_lower": [x, y, z], "com_upper": [x, y, z]}}}')


#: the prior weights ``--prior-weight auto`` tries
PRIOR_WEIGHT_GRID = (0.0, 0.1, 1.0, 10.0, 100.0)
#: ``--prior-weight auto`` takes the largest weight whose validation error is within this fraction of the best
PRIOR_WEIGHT_TOLERANCE = 0.01
#: the prior's weight without ``--validate`` to choose it: one unit of ½χ², where the prior weighs about as much as
#: the data on a direction of the bodies known to its own size (estimation.consistent.determination); the data
#: decide every direction they determine better than that
DEFAULT_PRIOR_WEIGHT = 1.0


def prior_weight(text: str) -> float | str:
    """``--prior-weight`` values: ``auto`` or a number (checked by :func:`check_consistent_arguments`)."""
    if text.strip().lower() == "auto":
        return "auto"
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number or 'auto', got {text!r}") from None


def check_consistent_arguments(args: argparse.Namespace) -> None:
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


def consistent_refit(args: argparse.Namespace, result, train, validation) -> ConsistentResult | None:
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


def print_consistent(consistent: ConsistentResult | None) -> None:
    if consistent is None:
        return
    estimate = consistent.estimate
    how = {"held-out": "chosen by the validation error", "given": "given",
           "default": "the default without --validate to choose it"}[consistent.prior_weight_choice]
    print(f"consistent (prior weight {estimate.prior_weight:g}: {how}; {estimate.solver['status']}, "
          f"{estimate.solver['time_s']:.2f} s): excess chi2 {estimate.excess_chi2:.4g}; active: "
          + (", ".join(estimate.active_bounds) or "none"))
    for name, theta, margin in zip(estimate.link_names, estimate.link_parameters(), estimate.margins):
        com = theta[1:4] / theta[0]
        print(f"  {name}: mass {theta[0]:.4g} kg, com [{com[0]:+.4f} {com[1]:+.4f} {com[2]:+.4f}] m, margin {margin:.2g}")
    if consistent.determination is not None:
        for line in consistent.determination.lines():
            print(line)
    for label, comparison in (("train", consistent.train), ("validation", consistent.validation)):
        if comparison is not None:
            print(f"consistent {label} MSE: " + "  ".join(f"{c} {v:.4g}" for c, v in comparison.mse.items()))
