"""``oed export``: a physically consistent identified model as a URDF (and friction.json) for other tools."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from estimation.identification.export import exported_model, exported_urdf, friction_document, implausible_links
from oed.cli.shared.common import OutputFiles, check_json_path, json_text
from oed.cli.shared.verbs import verb_summary


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "export",
        help=verb_summary("export"),
        description="From a result.json of `oed identify` (its chosen model when physically consistent, else its "
        "consistent alternative, named on stderr): the robot's URDF with every moving link's "
        "<inertial> replaced by the identified mass, centre of mass and inertia (the same joint and link names; a "
        "built-in robot is written from its description), and the joints' friction, offsets and armature as JSON. "
        "A body that is not plausible (degenerate, a mass ten times the description's or a tenth of it, a centre of "
        "mass beyond twice the link's reach) is refused unless --allow-implausible.",
    )
    parser.add_argument("--model", type=Path, required=True, help="result.json of oed identify --consistent")
    parser.add_argument("--urdf", dest="urdf_out", type=Path, required=True, metavar="URDF", help="URDF file to write")
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
    outputs = {"--urdf": args.urdf_out}
    if args.friction_out is not None:
        outputs["--friction"] = args.friction_out
    return outputs


def run(args: argparse.Namespace) -> int:
    model_path = args.model.expanduser().resolve()
    for option, path in (("--urdf", args.urdf_out), ("--friction", args.friction_out)):
        if path is not None and path.expanduser().resolve() == model_path:
            raise ValueError(f"{option} {path} is the model file (--model): it would be overwritten; write elsewhere")
    if args.urdf_out.suffix.lower() != ".urdf":
        raise ValueError(f"--urdf {args.urdf_out}: give a .urdf file name")
    if args.friction_out is not None:
        check_json_path(args.friction_out, "--friction")
    model, note = exported_model(args.model, alternative=args.alternative)  # refuses a model without bodies
    if note is not None:
        print(f"oed export: {note}", file=sys.stderr)
    text = exported_urdf(model)
    findings = implausible_links(model)
    if findings and not args.allow_implausible:
        raise ValueError("not exported: the consistent estimate holds bodies that are not plausible:\n  "
                         + "\n  ".join(findings) + "\nidentify again with a prior (--prior-weight, the default with "
                         "--validate chooses it) or link bounds (--link-bounds), or export them anyway with "
                         "--allow-implausible")
    friction = friction_document(model) if args.friction_out is not None else None
    with OutputFiles() as outputs:  # all files or none
        with outputs.open(args.urdf_out) as stream:
            stream.write(text)
        if friction is not None:
            with outputs.open(args.friction_out) as stream:
                stream.write(json_text(friction))
    for message in findings:
        print(f"oed export: warning: exported as asked (--allow-implausible), not plausible: {message}", file=sys.stderr)
    masses = ", ".join(f"{link[0]:.4g}" for link in model.file.consistent_links)
    print(f"{model.robot.name}: {model.robot.n_joints} bodies of the consistent estimate (masses {masses} kg)")
    print("wrote " + " and ".join(str(path) for path in (args.urdf_out, args.friction_out) if path is not None))
    return 0
