"""Writing result files safely: all of a run's files or none, usual permissions, strict JSON.

Used by the CLI verbs and by the library's own writers (measurement CSV/Parquet, figures), so it
depends on nothing else in the project.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from matplotlib.figure import Figure

FIGURE_DEFAULT_SUFFIX = ".png"


def file_mode() -> int:
    """Permissions of a newly created file under the process umask (``mkstemp`` alone gives 0600)."""
    umask = os.umask(0o022)
    os.umask(umask)
    return 0o666 & ~umask


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
    are removed, with the folders the run created for them. A failed run therefore leaves no
    output, neither a half-written file nor some of the files it was asked for.

    A run killed before it could clean up (SIGKILL, power loss) leaves its staged files behind;
    they are named ``.<target>.oed-<pid>-<random><suffix>`` and the next run staging the same
    target removes those whose process is gone (:func:`remove_stale_temporaries`). A file staged by this
    process is never staged again: a writer that stages its own output (:func:`save_figure`,
    :func:`atomic_output`) handed a staged path writes it directly (:func:`is_staged`), so that a run killed
    mid-write leaves one staged file, which the next run removes.

    The renames at the end are one after another: should the k-th fail (after staging succeeded in
    the same folder, which checks the usual causes), the earlier targets are already replaced.
    """

    def __init__(self) -> None:
        self._staged: list[tuple[Path, Path]] = []
        self._created_folders: list[Path] = []

    def __enter__(self) -> OutputFiles:
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 traceback: TracebackType | None) -> None:
        if kind is None:
            self.commit()
        else:
            self.discard()

    def stage(self, path: str | Path, *, default_suffix: str = ".tmp") -> Path:
        """A new temporary file that becomes ``path`` on :meth:`commit`.

        It lies in the same folder (created if missing) and has the same suffix, or
        ``default_suffix`` when ``path`` has none: writers that pick the format from the name
        (matplotlib) see the one meant (:meth:`stage_figure`).
        """
        path = Path(path)
        if is_staged(path):  # already staged by this process (an outer OutputFiles): written in place, renamed by it
            return path
        if any(path.resolve() == target.resolve() for _, target in self._staged):
            raise ValueError(f"{path} is written twice in one run: each output needs its own path")
        folder = self._output_folder(path)
        suffix = path.suffix or default_suffix
        remove_stale_temporaries(folder, path.name, suffix)
        try:
            handle, temporary = tempfile.mkstemp(prefix=f"{_temporary_prefix(path.name)}{os.getpid()}-",
                                                 suffix=suffix, dir=folder)
        except OSError as error:
            raise OSError(error.errno, f"cannot write {path}: {error.strerror}") from None
        os.close(handle)
        self._staged.append((Path(temporary), path))
        return Path(temporary)

    def stage_figure(self, path: str | Path) -> Path:
        """:meth:`stage` for a figure: a path without suffix is written as PNG."""
        return self.stage(path, default_suffix=FIGURE_DEFAULT_SUFFIX)

    @contextlib.contextmanager
    def open(self, path: str | Path, mode: str = "w") -> Iterator[Any]:
        """An open stream to the staged file of ``path``."""
        with open(self.stage(path), mode) as stream:
            yield stream

    def commit(self) -> None:
        """Rename every staged file onto its target, with the usual permissions."""
        mode = file_mode()
        target = None
        try:
            for temporary, target in self._staged:  # noqa: B007 (the target is named if chmod fails)
                os.chmod(temporary, mode)
            for temporary, target in self._staged:
                os.replace(temporary, target)
        except OSError as error:
            self.discard()
            raise OSError(error.errno, f"cannot write {target}: {error.strerror}") from None
        self._staged.clear()
        self._created_folders.clear()

    def discard(self) -> None:
        """Remove the staged files that were not committed, and the folders made for them if empty."""
        for temporary, _ in self._staged:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(temporary)
        self._staged.clear()
        for folder in reversed(self._created_folders):  # deepest first
            with contextlib.suppress(OSError):
                folder.rmdir()
        self._created_folders.clear()

    def _output_folder(self, path: Path) -> Path:
        """Create the folder of an output file (remembering what it made); ``OSError`` naming the output."""
        if path.is_dir():
            raise IsADirectoryError(f"cannot write {path}: it is a folder")
        folder = path.parent
        missing = []
        for candidate in (folder, *folder.parents):
            if candidate.exists():
                break
            missing.append(candidate)
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except FileExistsError:
            raise NotADirectoryError(f"cannot write {path}: {folder} exists and is not a folder") from None
        except OSError as error:
            raise OSError(error.errno, f"cannot write {path}: cannot create folder {folder} ({error.strerror})") from None
        self._created_folders.extend(reversed(missing))  # outermost first
        return folder


def _temporary_prefix(name: str) -> str:
    return f".{name}.oed-"


def is_staged(path: str | Path) -> bool:
    """Whether ``path`` is a file staged by this process (``.<target>.oed-<this pid>-<random><suffix>``)."""
    name = Path(path).name
    return name.startswith(".") and f".oed-{os.getpid()}-" in name


def _process_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True  # someone else's process, or cannot tell: keep its file
    return True


def remove_stale_temporaries(folder: Path, name: str, suffix: str) -> list[Path]:
    """Remove the staged files of ``name`` left in ``folder`` by runs whose process is gone; return them (those
    staged twice by earlier versions, ``..<target>.oed-<pid>-<random><suffix>.oed-…``, too)."""
    prefix = _temporary_prefix(name)
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        nested = entry.name.startswith("." + prefix)  # a staged file of a staged file
        if not ((entry.name.startswith(prefix) or nested) and entry.name.endswith(suffix)):
            continue
        pid_text = entry.name[len(prefix) + nested:].split("-", 1)[0]
        if not pid_text.isdigit() or int(pid_text) == os.getpid() or _process_alive(int(pid_text)):
            continue
        with contextlib.suppress(OSError):
            os.unlink(entry.path)
            removed.append(Path(entry.path))
    return removed


@contextlib.contextmanager
def atomic_output(path: str | Path, mode: str = "w") -> Iterator[Any]:
    """Write ``path`` through a temporary file renamed on success: no half-written output on error."""
    with OutputFiles() as outputs, outputs.open(path, mode) as stream:
        yield stream


def save_figure(figure: Figure, path: str | Path, *, dpi: int = 120) -> None:
    """Save a matplotlib figure atomically (no half-written file), format from the suffix (none: PNG)."""
    path = Path(path)
    with atomic_output(path, "wb") as stream:
        figure.savefig(stream, format=path.suffix.lstrip(".").lower() or FIGURE_DEFAULT_SUFFIX.lstrip("."), dpi=dpi)


def _finite_or_null(value: Any) -> Any:
    """``value`` with every non-finite float, at any depth of dicts, lists and tuples, as ``None``."""
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
