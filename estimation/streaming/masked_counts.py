"""``result.json``'s ``saturated_samples`` and ``channel_samples`` of a streamed run, as memory writes them
(:func:`~estimation.identification.prepared.saturated_sample_counts`,
:func:`~estimation.identification.prepared.channel_sample_counts`): each file's masked cells counted by one pass
over its kept rows (:func:`~estimation.streaming.chunks.masked_cells`), the same clipped sensors and held repeats
the streamed reader masks in its chunks; a file split at its holes counted segment by segment, as each segment is
read (:func:`~estimation.streaming.chunks.segment_sources`)."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path

from dynamics.models import IdentificationModel
from estimation.estimators.normal_equations import DEFAULT_CHUNK_SIZE
from estimation.streaming.chunks import MaskedCells, masked_cells, segment_sources, source_file

__all__ = ["streamed_mask_counts"]


def streamed_mask_counts(records: Mapping[str, Sequence[str | Path]], model: IdentificationModel, *,
                         chunk_size: int = DEFAULT_CHUNK_SIZE
                         ) -> tuple[dict[str, list[dict]] | None, dict[str, dict] | None]:
    """``(saturated_samples, channel_samples)`` of the streamed sources of each record (``train``, ``validation``,
    ``test``: ``records``' keys, in that order), in memory's form: per record the files whose torque or wrench
    sensor was clipped, with the samples left out per channel; per record whose channels' valid samples differ, the
    samples as recorded and each channel's valid ones. ``None`` where memory writes ``None`` (none found)."""
    saturated: dict[str, list[dict]] = {}
    channels: dict[str, dict] = {}
    for role, paths in records.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # said when the files are read
            sources = segment_sources(list(paths), model, chunk_size=chunk_size)  # a file with holes: its segments
        found: list[tuple[str | Path, MaskedCells]] = [(path, masked_cells(path, model, chunk_size=chunk_size))
                                                       for path in sources]
        entries = [{"file": str(source_file(path)[0]), "segment": _segment(path), "samples": dict(cells.clipped)}
                   for path, cells in found if cells.clipped]
        if entries:
            saturated[role] = entries
        samples = sum(cells.rows for _, cells in found)
        names = list(dict.fromkeys(name for _, cells in found for name in cells.channels))
        counts = {name: sum(cells.channels.get(name, cells.rows) for _, cells in found) for name in names}
        if any(count != samples for count in counts.values()):
            channels[role] = {"samples": int(samples), "channels": counts}
    return saturated or None, channels or None


def _segment(path: str | Path) -> int:
    """The 1-based segment of a streamed source (memory's ``metadata["segment"]``; 1: the whole file)."""
    segment = source_file(path)[1]
    return segment if isinstance(segment, int) else 1
