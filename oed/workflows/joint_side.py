"""Motor-side records and given joint zeros on the streamed path: read through joint-side copies.

The in-memory reader converts a motor-side record through the transmission (``--transmission``, a URDF's, the
built-in robot's) and applies ``--joint-offsets`` (the joints' zeros and directions) row by row as it reads
(:func:`estimation.data.motor_side.read_record_with_transmission`). The streamed path reads joint-side columns by
path in many passes; when such a run streams (``--chunk-size``, ``--scheduler``, ``--workers``, or records past
``--memory-budget``), each file that needs it is converted once, block by block, into a joint-side copy in a
temporary folder (:func:`estimation.data.motor_side.joint_side_copies`), the run reads the copies, and what it
writes and says names the files as given (:func:`named_as_given`). The copies are removed when the run ends.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

from dynamics.models import IdentificationModel
from dynamics.transmission import Transmission
from estimation.data.compressed_logs import data_suffix
from estimation.data.memory_budget import count_rows, estimate_in_memory
from estimation.data.motor_side import formatted_header, joint_side_copies, motor_columns
from oed.workflows.asbuilt import resolve_joint_directions, resolve_joint_offsets
from oed.workflows.memory_path import budget_of
from oed.workflows.options import RecordOptions, streaming_requested

__all__ = ["joint_side_records", "named_as_given", "records_to_read", "streams_converted"]

#: the record options whose files are read (``--data``, ``--validate``, ``--test``)
ROLES = ("data", "validate", "test")


def _files(args: RecordOptions) -> list[Any]:
    return [path for role in ROLES for path in (getattr(args, role, None) or ())]


def _needs_copies(args: RecordOptions, model: IdentificationModel) -> bool:
    """Whether a file of ``args`` holds motor-side columns (a controller's log its currents, named as the in-memory
    reader names them: :func:`~estimation.data.motor_side.formatted_header`), or ``--joint-offsets`` is given."""
    if getattr(args, "joint_offsets", None) is not None:
        return True
    for path in _files(args):
        path = Path(path)
        try:
            if path.is_file() and data_suffix(path) in (".csv", ".parquet") \
                    and motor_columns(formatted_header(path, model)):
                return True
        except (OSError, ValueError, ImportError):
            continue  # the reader names the fault
    return False


def streams_converted(args: RecordOptions, model: IdentificationModel, *, bytes_per_value: float,
                      in_memory_only: Callable[[], str | None]) -> bool:
    """Whether this run streams (as :func:`oed.workflows.memory_path.decide_path` decides) and reads motor-side
    columns or ``--joint-offsets``: then it reads joint-side copies (:func:`joint_side_records`)."""
    if not _needs_copies(args, model):
        return False
    if streaming_requested(args):
        return True
    try:
        rows = [count_rows(path) for path in _files(args)]
    except (OSError, ValueError, ImportError):
        return False
    need = estimate_in_memory(rows, model, bytes_per_value=bytes_per_value, budget=budget_of(args))
    return need.stream and in_memory_only() is None


@contextmanager
def joint_side_records(args: RecordOptions, model: IdentificationModel, transmission: Transmission | None,
                       ) -> Iterator[tuple[RecordOptions, dict[str, str]]]:
    """``args`` reading joint-side copies of its files (module docstring), without ``--joint-offsets`` (applied in
    the copies), and the copies' names against the files as given (for :func:`named_as_given`). The copies are
    removed on leaving."""
    folder = Path(tempfile.mkdtemp(prefix="oed-joint-side-"))
    try:
        robot = model.robot
        offsets = resolve_joint_offsets(args, robot)
        directions = resolve_joint_directions(args, robot)
        names: dict[str, str] = {}
        changes: dict[str, Any] = {}
        for role in ROLES:
            paths = getattr(args, role, None)
            if not paths:
                continue
            copies = joint_side_copies(paths, folder / role, n_joints=robot.n_joints, transmission=transmission,
                                       joint_offsets=offsets, joint_directions=directions, model=model)
            names.update({str(copy): str(path) for copy, path in zip(copies, paths) if str(copy) != str(path)})
            changes[role] = type(paths)(type(path)(copy) if isinstance(path, Path) else str(copy)
                                        for copy, path in zip(copies, paths))
        yield replace(args, joint_offsets=None, **changes), names
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@contextmanager
def records_to_read(args: RecordOptions, model: IdentificationModel, transmission: Transmission | None, *,
                    bytes_per_value: float, in_memory_only: Callable[[], str | None],
                    ) -> Iterator[tuple[RecordOptions, dict[str, str]]]:
    """What a verb reads: ``(args, {})`` as given, or, when the run streams motor-side columns or
    ``--joint-offsets`` (:func:`streams_converted`), the joint-side copies (:func:`joint_side_records`), removed on
    leaving."""
    if streams_converted(args, model, bytes_per_value=bytes_per_value, in_memory_only=in_memory_only):
        with joint_side_records(args, model, transmission) as converted:
            yield converted
    else:
        yield args, {}


def named_as_given(value: Any, names: Mapping[str, str]) -> Any:
    """``value`` (a document: dicts, lists, tuples, strings) with every copy's name replaced by its file's as
    given (:func:`joint_side_records`)."""
    if not names:
        return value
    if isinstance(value, str):
        for copy, path in names.items():
            value = value.replace(copy, path)
        return value
    if isinstance(value, Mapping):
        return {key: named_as_given(item, names) for key, item in value.items()}
    if isinstance(value, list):
        return [named_as_given(item, names) for item in value]
    if isinstance(value, tuple):
        return tuple(named_as_given(item, names) for item in value)
    return value
