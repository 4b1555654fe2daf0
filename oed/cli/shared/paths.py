"""One check for every verb: no output file may be an input file or another output file, and each output's folder
must be one this process can write in.

Run by :func:`oed.cli.main` before the verb's work, from the option names the verbs share (a verb
adds the files it derives from its options through ``derived_outputs``). Without it, ``--out`` equal
to ``--data`` would replace the measurements by the result, and ``--csv`` equal to ``--out`` would
keep only one of the two files, both with exit code 0; and an output in a folder that cannot be written would be
refused only after the whole run.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

#: options that name files a verb reads
INPUT_OPTIONS: tuple[str, ...] = ("data", "validate", "trajectory", "bounds", "aprbs", "urdf", "transmission", "prior",
                                 "link_bounds", "joint_offsets")
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


def check_writable(label: str, path: Path, *, folder: bool = False) -> None:
    """Raise ``OSError`` naming ``label`` when the output ``path`` (a ``folder`` itself, else a file) cannot be
    written: the nearest folder of it that exists is not a folder, or no file can be created in it (a probe file,
    removed at once: permissions, a read-only file system). A ``folder`` output that is a file is left to the verb,
    whose message says what it writes there."""
    target = path.expanduser().absolute()
    existing = target if folder and target.is_dir() else target.parent
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise NotADirectoryError(f"{label} {path}: {existing} is not a folder")
    try:
        handle, probe = tempfile.mkstemp(prefix=".oed-probe-", dir=existing)
    except OSError as error:
        raise PermissionError(f"{label} {path}: cannot write in {existing} ({error.strerror})") from None
    os.close(handle)
    with contextlib.suppress(OSError):
        os.unlink(probe)


def check_paths(args: argparse.Namespace,
                derived_outputs: Callable[[argparse.Namespace], dict[str, Path]] | None = None) -> None:
    """Raise ``ValueError`` when a path option is empty, an output is a folder or also an input, or
    two outputs coincide; ``OSError`` when an output cannot be written (:func:`check_writable`)."""
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
    folders = tuple(getattr(args, "folder_options", ()))
    for label, (role, path) in named.items():
        if role == "output":
            check_writable(label, path, folder=label.split(" ")[0].removeprefix("--").replace("-", "_") in folders)
