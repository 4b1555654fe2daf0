"""One check for every verb: no output file may be an input file or another output file.

Run by :func:`oed.cli.main` before the verb's work, from the option names the verbs share (a verb
adds the files it derives from its options through ``derived_outputs``). Without it, ``--out`` equal
to ``--data`` would replace the measurements by the result, and ``--csv`` equal to ``--out`` would
keep only one of the two files, both with exit code 0.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable
from pathlib import Path

#: options that name files a verb reads
INPUT_OPTIONS: tuple[str, ...] = ("data", "validate", "trajectory", "bounds", "aprbs", "urdf", "transmission", "prior",
                                 "link_bounds")
#: options that name files a verb writes (or folders, for the options a verb lists in ``folder_options``)
OUTPUT_OPTIONS: tuple[str, ...] = ("out", "csv", "plot", "figure", "truth", "report")


def _flag(option: str) -> str:
    return f"--{option.replace('_', '-')}"


def _named_paths(args: argparse.Namespace) -> dict[str, tuple[str, Path]]:
    """``{flag: (role, path)}``, the inputs first."""
    named: dict[str, tuple[str, Path]] = {}
    folders = tuple(getattr(args, "folder_options", ()))
    for role, options in (("input", INPUT_OPTIONS), ("output", OUTPUT_OPTIONS)):
        for option in options:
            given = getattr(args, option, None)
            if given is None:
                continue
            values = given if isinstance(given, (list, tuple)) else [given]  # repeatable options (--data a --data b)
            for number, value in enumerate(values, start=1):
                if not str(value).strip():
                    raise ValueError(f"{_flag(option)} is empty: give a file name")
                if role == "output" and option not in folders and Path(value).is_dir():  # Path("") is "."
                    raise ValueError(f"{_flag(option)} {value} is a folder: give a file name")
                named[_flag(option) + (f" #{number}" if len(values) > 1 else "")] = (role, Path(value))
        effect_values = getattr(args, "effect_values", None)  # JSON text or a file of it
        if role == "input" and effect_values and not effect_values.lstrip().startswith("{") \
                and os.path.isfile(effect_values):
            named["--effect-values"] = ("input", Path(effect_values))
    return named


def check_paths(args: argparse.Namespace,
                derived_outputs: Callable[[argparse.Namespace], dict[str, Path]] | None = None) -> None:
    """Raise ``ValueError`` when a path option is empty, an output is a folder or also an input, or
    two outputs coincide."""
    named = _named_paths(args)
    if derived_outputs is not None:
        for label, path in derived_outputs(args).items():
            named[label] = ("output", Path(path))
    seen: dict[Path, str] = {}
    for label, (role, path) in named.items():
        key = path.expanduser().resolve()
        if key in seen:
            first = seen[key]
            if role == "output" and named[first][0] == "input":
                raise ValueError(f"{label} {path} is the input file of {first}: it would be overwritten; "
                                 "write the result elsewhere")
            if role == "output":
                raise ValueError(f"{first} and {label} are the same file ({path}): each output needs its own path")
            continue  # the same file read twice (e.g. --data and --validate) is the verb's business
        seen[key] = label
