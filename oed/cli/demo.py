"""``oed demo``: the main job on the built-in PUMA 560 (``make demo``); see :mod:`oed.demo`."""

from __future__ import annotations

import argparse

from oed.demo import run_demo
from oed.cli.shared.verbs import verb_summary


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "demo",
        help=verb_summary("demo"),
    )
    parser.add_argument("--out", default="out/demo", help="folder for the report and figures (default: out/demo)")
    parser.set_defaults(folder_options=("out",))  # --out names a folder (oed.cli.shared.paths)
    return parser


def run(args: argparse.Namespace) -> int:
    run_demo(args.out)
    return 0
