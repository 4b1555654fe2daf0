"""``oed export``: a physically consistent identified model as a URDF (and friction.json) for other tools
(the work: :func:`oed.workflows.export.export`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from oed.cli.shared.common import print_lines, print_warnings
from oed.cli.shared.verbs import verb_summary
from oed.workflows.export import check_outputs, export


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "export",
        help=verb_summary("export"),
        description="From a result.json (oed identify) or report.json (oed diagnose) whose chosen model is physically "
        "consistent, else from its consistent alternative (the default answer keeps one; `oed identify --consistent` "
        "chooses it): the robot's URDF with every moving link's "
        "<inertial> replaced by the identified mass, centre of mass and inertia (the same joint and link names; a "
        "built-in robot is written from its description), and the joints' friction, offsets and armature as JSON. "
        "A body that is not plausible (degenerate, a mass ten times the description's or a tenth of it, a centre of "
        "mass beyond twice the link's reach) is refused unless --allow-implausible.",
    )
    parser.add_argument("--model", type=Path, required=True, help="result.json (oed identify) or report.json (oed diagnose) holding a physically consistent "
                             "model, chosen or as the alternative 'consistent'")
    parser.add_argument("--urdf", dest="urdf_out", type=Path, metavar="URDF", help="URDF file to write")
    parser.add_argument("--mjcf", dest="mjcf_out", type=Path, metavar="XML",
                        help="MuJoCo MJCF file to write: the bodies, joint armature, damping (viscous), frictionloss "
                             "(Coulomb), gravity; what MuJoCo cannot express is listed in a comment and here")
    parser.add_argument("--friction", dest="friction_out", type=Path, metavar="JSON",
                        help="friction.json to write: per joint viscous, coulomb, offset, armature…, other effects")
    parser.add_argument("--alternative", metavar="NAME",
                        help="export the alternative model NAME of the file (only 'consistent' has bodies); default: "
                             "the chosen model when it is physically consistent, else the consistent alternative")
    parser.add_argument("--allow-implausible", action="store_true",
                        help="write the files even when a body is not plausible (each named on stderr); without it "
                             "such a model is refused (exit 2, nothing written)")
    return parser


def derived_outputs(args: argparse.Namespace) -> dict[str, Path]:
    """``--urdf`` and ``--friction``: outputs here (checked against each other by :func:`oed.cli.shared.paths.check_paths`)."""
    outputs = {option: path for option, path in (("--urdf", args.urdf_out), ("--mjcf", args.mjcf_out))
               if path is not None}
    if args.friction_out is not None:
        outputs["--friction"] = args.friction_out
    return outputs


def run(args: argparse.Namespace) -> int:
    model_path = args.model.expanduser().resolve()
    written = (("--urdf", args.urdf_out), ("--mjcf", args.mjcf_out), ("--friction", args.friction_out))
    if args.urdf_out is None and args.mjcf_out is None:
        raise ValueError("give --urdf FILE.urdf or --mjcf FILE.xml (or both): what to write")
    for option, path in written:
        if path is not None and path.expanduser().resolve() == model_path:
            raise ValueError(f"{option} {path} is the model file (--model): it would be overwritten; write elsewhere")
    check_outputs(args.urdf_out, mjcf=args.mjcf_out, friction=args.friction_out)  # before any work
    result = export(model=args.model, allow_implausible=args.allow_implausible, mjcf=args.mjcf_out is not None,
                    alternative=args.alternative)
    result.write(args.urdf_out, mjcf=args.mjcf_out, friction=args.friction_out)
    print_warnings("export", result.warnings)
    print_lines(result.summary())
    print("wrote " + " and ".join(str(path) for _, path in written if path is not None))
    return 0
