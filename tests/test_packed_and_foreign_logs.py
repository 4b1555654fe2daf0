"""Logs as they come, read by every verb in memory and streamed (h-logs4): a CSV file packed by gzip, bzip2, xz or in
a one-file ZIP archive; other loggers' habits (a European CSV, units in the column names, integer nanosecond stamps,
duplicated stamps with other values, a header repeated mid-file, trailing empty columns); channels starting late or
stopping early, long tables and newest-first logs on the streamed path.

The cheap tests read a PUMA's three joints' 2 s record at 250 Hz each way, in memory and block by block, against the
plain file's reading (exactly, or to 1e-12 where a conversion rounds). The slow test runs the default ``oed
identify`` (told the plain fit's class) and ``oed diagnose`` in memory and streamed (``--chunk-size``) on each habit,
then ``oed predict`` on a test record no choice saw, against the plain fit (:mod:`tests.test_unseen_robot_labs`)."""

from __future__ import annotations

import bz2
import gzip
import lzma
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dynamics.models import build_model
from dynamics.robots import load_robot
from tests.test_unseen_robots import FRICTION, Log, truth, urdf_of, write_record


@pytest.fixture(scope="module")
def puma3(tmp_path_factory):
    """A PUMA's first three joints, one clean 2 s record at 250 Hz (no velocity column) and its model."""
    folder = tmp_path_factory.mktemp("puma3")
    urdf = urdf_of("puma560:3", folder)
    model = build_model(load_robot(urdf=urdf), "internal", FRICTION)
    write_record(model, truth(model), Log(2.0, 250.0, velocity=False), 11, folder / "clean.csv")
    return model, folder / "clean.csv"


def read_both(path, model, chunk_size: int = 100):
    """The record read in memory and streamed (its blocks joined), and the warnings said."""
    from estimation.data.records import read_measurements
    from estimation.streaming.chunks import read_chunks, segment_sources

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        memory = read_measurements(path, model=model)
        sources = segment_sources([path], model, chunk_size=chunk_size)
        chunks = [chunk for source in sources for chunk in read_chunks(source, model, chunk_size=chunk_size)]
    streamed = {name: np.concatenate([getattr(chunk, name) for chunk in chunks]) for name in ("t", "q", "tau")}
    return memory, streamed, [str(warning.message) for warning in caught]


def packed(path: Path, how: str) -> Path:
    """``path`` packed by ``how`` (gzip, bzip2, xz, zip) beside it."""
    if how == "zip":
        target = path.with_suffix(".zip")
        with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.write(path, path.name)
        return target
    compress, ending = {"gzip": (gzip.compress, ".gz"), "bzip2": (bz2.compress, ".bz2"),
                        "xz": (lzma.compress, ".xz")}[how]
    target = path.with_name(path.name + ending)
    target.write_bytes(compress(path.read_bytes()))
    return target


@pytest.mark.parametrize("how", ["gzip", "bzip2", "xz", "zip"])
def test_a_packed_csv_file_is_read_as_the_file_it_packs_in_memory_and_streamed(puma3, tmp_path, how):
    """``train.csv.gz``, ``.bz2``, ``.xz`` or a ZIP archive holding one CSV file: read as the file it packs, in
    memory and block by block (the same samples, exactly), its rows counted for the memory budget as the plain
    file's. At 8322458 each was refused ("unknown data format '.gz' … unpack it first")."""
    from estimation.data.memory_budget import count_rows

    model, clean = puma3
    plain, _, _ = read_both(clean, model)
    path = packed(clean, how)
    memory, streamed, _ = read_both(path, model)
    for name in ("t", "q", "tau"):
        assert np.array_equal(getattr(memory, name), getattr(plain, name)), name
        assert np.array_equal(streamed[name], getattr(plain, name)), name
    assert count_rows(path) == count_rows(clean)


def test_packed_files_the_readers_cannot_read_are_named(puma3, tmp_path):
    """A ZIP archive of two files, a packed Parquet file, a truncated gzip file and a zstd file: each a
    ``MeasurementError`` naming the problem, in memory and streamed."""
    from estimation.data import MeasurementError
    from estimation.data.records import read_measurements
    from estimation.streaming.chunks import read_chunks

    model, clean = puma3
    two = tmp_path / "two.zip"
    with zipfile.ZipFile(two, "w") as archive:
        archive.write(clean, "train.csv")
        archive.write(clean, "validate.csv")
    truncated = tmp_path / "cut.csv.gz"
    truncated.write_bytes(gzip.compress(clean.read_bytes())[:-200])
    parquet = tmp_path / "run.parquet.gz"
    parquet.write_bytes(gzip.compress(b"PAR1"))
    zstd = tmp_path / "run.csv.zst"
    zstd.write_bytes(b"(\xb5/\xfd")
    for path, said in ((two, r"a ZIP archive holding 2 files \(train.csv, validate.csv\)"),
                       (truncated, "cannot unpack .*cut.csv.gz.*truncated or corrupt"),
                       (parquet, "a gzip-packed '.parquet' file; the readers unpack CSV files only"),
                       (zstd, r"compressed file \(.zst, not read.*unpack it first \(its inner name 'run.csv'\)")):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with pytest.raises(MeasurementError, match=said):
                read_measurements(path, model=model)
            with pytest.raises(MeasurementError, match=said):
                list(read_chunks(path, model, chunk_size=100))
