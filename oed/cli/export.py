"""``oed export``: a physically consistent identified model as a URDF (and friction.json) for other tools."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from estimation.identification.export import exported_mjcf, exported_urdf, friction_document, implausible_links
from estimation.identification.identified_model import IdentifiedModel
from oed.cli.shared.common import OutputFiles, check_json_path, json_text
from oed.cli.shared.verbs import verb_summary


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "export",
        help=verb_summary("export"),
        description="From a result.json of `oed identify --consistent`: the robot's URDF with every moving link's "
        "<inertial> replaced by the identified mass, centre of mass and inertia (the same joint and link names; a "
        "built-in robot is written from its description), and the joints' friction, offsets and armature as JSON. "
        "A body that is not plausible (degenerate, a mass ten times the description's or a tenth of it, a centre of "
        "mass beyond twice the link's reach) is refused unless --allow-implausible. --mjcf writes the model for MuJoCo "
        "(bodies, armature, damping, frictionloss, gravity; what MuJoCo cannot express is listed).",
    )
    parser.add_argument("--model", type=Path, required=True, help="result.json of oed identify --consistent")
    parser.add_argument("--urdf", dest="urdf_out", type=Path, metavar="URDF", help="URDF file to write")
    parser.add_argument("--mjcf", dest="mjcf_out", type=Path, metavar="XML",
                        help="MuJoCo MJCF file to write: the bodies, joint armature, damping (viscous), frictionloss "
                             "(Coulomb), gravity; what MuJoCo cannot express is listed in a comment and here")
    parser.add_argument("--friction", dest="friction_out", type=Path, metavar="JSON",
                        help="friction.json to write: per joint viscous, coulomb, offset, armature…, other effects")
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
    if args.urdf_out is not None and args.urdf_out.suffix.lower() != ".urdf":
        raise ValueError(f"--urdf {args.urdf_out}: give a .urdf file name")
    if args.mjcf_out is not None and args.mjcf_out.suffix.lower() != ".xml":
        raise ValueError(f"--mjcf {args.mjcf_out}: give an .xml file name")
    if args.friction_out is not None:
        check_json_path(args.friction_out, "--friction")
    model = IdentifiedModel.load(args.model)  # exported_urdf refuses a model without a consistent estimate
    text = exported_urdf(model) if args.urdf_out is not None else None
    mjcf = exported_mjcf(model) if args.mjcf_out is not None else None
    findings = implausible_links(model)
    if findings and not args.allow_implausible:
        raise ValueError("not exported: the consistent estimate holds bodies that are not plausible:\n  "
                         + "\n  ".join(findings) + "\nidentify again with a prior (--prior-weight, the default with "
                         "--validate chooses it) or link bounds (--link-bounds), or export them anyway with "
                         "--allow-implausible")
    friction = friction_document(model) if args.friction_out is not None else None
    with OutputFiles() as outputs:  # all files or none
        for path, content in ((args.urdf_out, text), (args.mjcf_out, None if mjcf is None else mjcf.text)):
            if path is not None:
                with outputs.open(path) as stream:
                    stream.write(content)
        if friction is not None:
            with outputs.open(args.friction_out) as stream:
                stream.write(json_text(friction))
    for message in findings:
        print(f"oed export: warning: exported as asked (--allow-implausible), not plausible: {message}", file=sys.stderr)
    masses = ", ".join(f"{link[0]:.4g}" for link in model.file.consistent_links)
    print(f"{model.robot.name}: {model.robot.n_joints} bodies of the consistent estimate (masses {masses} kg)")
    for note in () if mjcf is None else mjcf.notes:
        print(f"not expressed in MuJoCo (listed in {args.mjcf_out}): {note}")
    print("wrote " + " and ".join(str(path) for _, path in written if path is not None))
    return 0
