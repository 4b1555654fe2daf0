"""``--consistent`` of ``oed identify`` and ``oed diagnose``: the checks of its options, the refit (the prior's weight
chosen in :mod:`estimation.consistent.identification`: :data:`PRIOR_WEIGHT_GRID`, :data:`PRIOR_WEIGHT_TOLERANCE`,
:data:`DEFAULT_PRIOR_WEIGHT`), and its summary lines."""

from __future__ import annotations

import re

from typing import Any

import numpy as np

from estimation.consistent.identification import (
    DEFAULT_PRIOR_WEIGHT,
    PRIOR_WEIGHT_GRID,
    PRIOR_WEIGHT_TOLERANCE,
    ConsistentResult,
    consistent_fit,
    load_link_bounds,
    load_prior,
)
from estimation.consistent.model_selection import ConsistentSettings

__all__ = ["DEFAULT_PRIOR_WEIGHT", "PRIOR_WEIGHT_GRID", "PRIOR_WEIGHT_TOLERANCE", "check_consistent_arguments",
           "consistent_lines", "consistent_refit", "consistent_settings"]


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
    """The consistent refit of ``result`` (``None`` without ``consistent``), its prior weight given or chosen on the
    validation record (:func:`estimation.consistent.identification.consistent_fit`); shaped laws and a delay held at
    their fitted values."""
    if not args.consistent:
        return None
    robot = result.model.robot
    prior = None if args.prior is None else load_prior(args.prior, robot)
    bounds = None if args.link_bounds is None else load_link_bounds(args.link_bounds, robot)
    return consistent_fit(result, train, validation, prior_weight=args.prior_weight, prior=prior,
                          prior_source=args.prior or "robot description", bounds=bounds)


def scaled_prior_source(scale: float) -> str:
    """The ``prior_source`` (``consistent.prior`` of ``result.json``) of the description's bodies taken at the recorded
    torques' ``scale``; :func:`prior_source_scale` reads it back."""
    return f"robot description times {scale:.6g} (the recorded torques' scale)"


def prior_source_scale(source: Any) -> float | None:
    """The scale of a ``prior_source`` written by :func:`scaled_prior_source` (a result's ``consistent.prior``: the
    description's bodies at the recorded torques' scale, a description in grams giving about 0.001), else ``None``."""
    found = re.fullmatch(r"robot description times (\S+) \(the recorded torques' scale\)", source) \
        if isinstance(source, str) else None
    if found is None:
        return None
    try:
        value = float(found.group(1))
    except ValueError:
        return None
    return value if np.isfinite(value) and value > 0 else None


def consistent_settings(args: Any, robot: Any) -> ConsistentSettings:
    """How the consistent candidate of the default choice is fitted: ``prior_weight``, ``prior``, ``link_bounds``
    (:class:`estimation.consistent.model_selection.ConsistentSettings`); without ``prior``, the description's bodies
    times ``prior_scale`` when the verb set it (the recorded torques' scale: a description in grams), said in
    ``prior_source``."""
    scale = getattr(args, "prior_scale", None)
    if args.prior is None and scale is not None:
        prior, source = scale * robot.standard_parameters, scaled_prior_source(scale)
    else:
        prior = None if args.prior is None else load_prior(args.prior, robot)
        source = args.prior or "robot description"
    return ConsistentSettings(prior_weight=args.prior_weight, prior=prior, prior_source=source,
                              bounds=None if args.link_bounds is None else load_link_bounds(args.link_bounds, robot))


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
    if estimate.effect_prior:
        lines.append("  the description's joint terms as prior (armature, damping, frictionloss): " + ", ".join(
            f"{name} {value:.4g} -> {estimate.effect_values()[name]:.4g}" for name, value in estimate.effect_prior.items()))
    for name, theta, margin in zip(estimate.link_names, estimate.link_parameters(), estimate.margins):
        com = theta[1:4] / theta[0]
        lines.append(f"  {name}: mass {theta[0]:.4g} kg, com [{com[0]:+.4f} {com[1]:+.4f} {com[2]:+.4f}] m, margin {margin:.2g}")
    if consistent.determination is not None:
        for line in consistent.determination.lines():
            lines.append(line)
    for label, comparison in (("train", consistent.train), ("validation", consistent.validation)):
        if comparison is not None and comparison.mse is not None:  # sums of filtered channels: not the recording
            lines.append(f"consistent {label} MSE (vs recorded): " + "  ".join(f"{c} {v:.4g}" for c, v in comparison.mse.items()))
    return lines
