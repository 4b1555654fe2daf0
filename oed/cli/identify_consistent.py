"""``oed identify --consistent``: options, the refit and its summary (kept apart from identify.py)."""

from __future__ import annotations

import argparse

import numpy as np

from dynamics.robot import RobotModel
from estimation.consistent.identification import ConsistentResult, load_link_bounds, load_prior
from estimation.consistent.model_selection import (
    DEFAULT_PRIOR_WEIGHT,
    PRIOR_WEIGHT_GRID,
    PRIOR_WEIGHT_TOLERANCE,
    ConsistentSettings,
)


def add_consistent_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("physical consistency")
    group.add_argument("--consistent", action="store_true",
                       help="choose the physically consistent fit (every link a real rigid body, friction/armature >= 0; "
                            "log-Cholesky map, IPOPT) whatever the validation error says; without it the consistent "
                            "fit is a candidate of the default choice (model_selection in the result)")
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


def consistent_settings(args: argparse.Namespace, robot: RobotModel) -> ConsistentSettings:
    """How the consistent candidate is fitted: ``--prior-weight``, ``--prior``, ``--link-bounds``."""
    return ConsistentSettings(prior_weight=args.prior_weight,
                              prior=None if args.prior is None else load_prior(args.prior, robot),
                              prior_source=args.prior or "robot description",
                              bounds=None if args.link_bounds is None else load_link_bounds(args.link_bounds, robot))


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
