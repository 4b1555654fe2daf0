"""``--consistent`` of ``oed identify`` and ``oed diagnose``: its options (the refit and the prior-weight choice: :mod:`oed.workflows.consistent`)."""

from __future__ import annotations

import argparse

from estimation.consistent.identification import DEFAULT_PRIOR_WEIGHT, PRIOR_WEIGHT_GRID, PRIOR_WEIGHT_TOLERANCE


def add_consistent_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("physical consistency")
    group.add_argument("--consistent", action="store_true",
                       help="choose the physically consistent fit (every link a real rigid body, friction/armature >= 0; "
                            "log-Cholesky map, IPOPT) whatever the validation error says; without it the consistent "
                            "fit is a candidate of oed identify's default choice (model_selection in the result); "
                            "oed diagnose: refit the adopted model consistently")
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
