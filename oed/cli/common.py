"""Options shared by the verbs: which robot, and writing output files safely."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import tempfile
from collections.abc import Iterator
from typing import Any
from pathlib import Path

from dynamics.robot import RobotModel
from dynamics.robots import BUILT_IN_ROBOTS, load_robot


def add_robot_arguments(parser: argparse.ArgumentParser, *, default: str | None = "puma560") -> None:
    """``--robot NAME``, ``--urdf FILE`` (which wins) and ``--joints N``."""
    group = parser.add_argument_group("robot")
    group.add_argument(
        "--robot", default=default, help=f"built-in robot: {', '.join(sorted(BUILT_IN_ROBOTS))} (default: {default})"
    )
    group.add_argument("--urdf", type=Path, help="URDF file of a serial chain (stands in for --robot)")
    group.add_argument("--joints", type=int, help="keep only the first N joints (the PUMA paper uses 3)")


def seed(text: str) -> int:
    """``--seed`` values: non-negative integers (what ``numpy.random`` accepts), checked by argparse."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a non-negative integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a non-negative integer, got {value}")
    return value


def robot_from_arguments(args: argparse.Namespace) -> RobotModel:
    return load_robot(args.robot, urdf=args.urdf, joints=args.joints)


def _file_mode() -> int:
    """Permissions of a newly created file under the process umask (``mkstemp`` alone gives 0600)."""
    umask = os.umask(0o022)
    os.umask(umask)
    return 0o666 & ~umask


def _output_folder(path: Path) -> Path:
    """Create the folder of an output file; raise ``OSError`` naming the output when it cannot be."""
    if path.is_dir():
        raise IsADirectoryError(f"cannot write {path}: it is a folder")
    folder = path.parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise NotADirectoryError(f"cannot write {path}: {folder} exists and is not a folder") from None
    except OSError as error:
        raise OSError(error.errno, f"cannot write {path}: cannot create folder {folder} ({error.strerror})") from None
    return folder


def check_figure_path(path: str | Path | None) -> None:
    """Fail before any work when a figure's suffix names a format matplotlib cannot write (none: PNG)."""
    if path is None:
        return
    from matplotlib.backend_bases import FigureCanvasBase

    suffix = Path(path).suffix.lstrip(".").lower()
    formats = FigureCanvasBase.get_supported_filetypes()
    if suffix and suffix not in formats:
        raise ValueError(f"figure {path}: unknown format {suffix!r}; use one of {', '.join(sorted(formats))}")


class OutputFiles:
    """The output files of one run, staged beside their targets and renamed into place together.

    Use as a context manager: :meth:`open` (or :meth:`stage`, for a library call that writes by
    path) gives a temporary file in the target's folder with the target's suffix; when the block
    ends without an error every staged file is renamed onto its target, and on any error all
    are removed. A failed run therefore leaves no output at all, neither a half-written file nor
    some of the files it was asked for.
    """

    def __init__(self) -> None:
        self._staged: list[tuple[Path, Path]] = []

    def __enter__(self) -> OutputFiles:
        return self

    def __exit__(self, kind, value, traceback) -> None:
        if kind is None:
            self.commit()
        else:
            self.discard()

    def stage(self, path: str | Path) -> Path:
        """A new temporary file that becomes ``path`` on :meth:`commit` (same folder, same suffix)."""
        path = Path(path)
        folder = _output_folder(path)
        try:
            handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix or ".tmp", dir=folder)
        except OSError as error:
            raise OSError(error.errno, f"cannot write {path}: {error.strerror}") from None
        os.close(handle)
        self._staged.append((Path(temporary), path))
        return Path(temporary)

    @contextlib.contextmanager
    def open(self, path: str | Path, mode: str = "w") -> Iterator:
        """An open stream to the staged file of ``path``."""
        with open(self.stage(path), mode) as stream:
            yield stream

    def commit(self) -> None:
        """Rename every staged file onto its target, with the usual permissions."""
        mode = _file_mode()
        try:
            for temporary, _ in self._staged:
                os.chmod(temporary, mode)
            for temporary, path in self._staged:
                os.replace(temporary, path)
        except OSError as error:
            self.discard()
            raise OSError(error.errno, f"cannot write {error.filename}: {error.strerror}") from None
        self._staged.clear()

    def discard(self) -> None:
        """Remove the staged files that were not committed."""
        for temporary, _ in self._staged:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(temporary)
        self._staged.clear()


@contextlib.contextmanager
def atomic_output(path: str | Path, mode: str = "w") -> Iterator:
    """Write ``path`` through a temporary file renamed on success: no half-written output on error."""
    with OutputFiles() as outputs, outputs.open(path, mode) as stream:
        yield stream


def _finite_or_null(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: _finite_or_null(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_or_null(item) for item in value]
    return value


def json_text(document: Any) -> str:
    """``document`` as strict JSON (RFC 8259): a NaN or infinite number becomes ``null``, since
    ``NaN``/``Infinity``, Python's default, break other tools' parsers (jq, JavaScript, pandas)."""
    return json.dumps(_finite_or_null(document), indent=2, allow_nan=False) + "\n"
