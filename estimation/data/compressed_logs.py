"""Logs packed for storage: a CSV file compressed whole (gzip ``.csv.gz``, bzip2 ``.csv.bz2``, xz ``.csv.xz``, zstd
``.csv.zst``) or a ZIP archive holding one CSV file, read as the file it packs, in memory and block by block (the
streamed path), without unpacking it on disk. zstd is not in the standard library: read through the ``zstandard``
package where it is importable (the one pandas uses; the project's ``zstd`` extra installs it), refused naming it
otherwise (:class:`ZstdSupportError`).

Every reader of a table file asks :func:`data_suffix` for the format (``.csv`` for ``run.csv.gz``) and opens the
bytes with :func:`open_binary` (or :func:`open_text` for its first lines: the dialect, a units row): the
decompressor streams the file, so a streamed reader's memory stays one block's whatever the file's length. A packer
not read (7-Zip, RAR, lz4, tar), a ZIP archive holding several files or none, a packed Parquet file
(Parquet compresses its own columns) and a file whose packing is corrupt are a :class:`CompressedLogError` naming the
problem and what to do.
"""

from __future__ import annotations

import bz2
import contextlib
import gzip
import io
import lzma
import os
import zipfile
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from estimation.data.loading import MeasurementError

#: the endings of a packed file read as the file it packs, and the packer of each
COMPRESSIONS: dict[str, str] = {".gz": "gzip", ".bz2": "bzip2", ".xz": "xz", ".zst": "zstd", ".zip": "ZIP"}
#: the endings of packers not read: named, not read (unpack such a file first)
OTHER_PACKERS: tuple[str, ...] = (".7z", ".rar", ".lz4", ".tar", ".tgz")
#: what to install to read a zstd-packed file (the package pandas reads zstd with; the project's ``zstd`` extra)
ZSTD_PACKAGE = "zstandard"
#: the compressed bytes read at a time from a zstd-packed file
ZSTD_READ = 1 << 16
#: what a corrupt or truncated packed file raises while it is read
UNPACKING_ERRORS = (EOFError, lzma.LZMAError, zlib.error, zipfile.BadZipFile, gzip.BadGzipFile)


class CompressedLogError(MeasurementError):
    """A packed log that cannot be read as the file it packs: a packer not read, a ZIP archive of several files, a
    packed Parquet file, a corrupt or truncated file."""


class ZstdSupportError(CompressedLogError):
    """A zstd-packed log where the ``zstandard`` package is not importable: the message names what to install."""


def is_packed(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` ends as a file packed by :data:`COMPRESSIONS`' packers (``run.csv.gz``, ``run.zip``)."""
    return Path(path).suffix.lower() in COMPRESSIONS


def zip_member(path: str | os.PathLike[str]) -> str:
    """The one file of the ZIP archive ``path`` (folders and a Mac's ``__MACOSX/`` and dot files left aside).

    Raises
    ------
    CompressedLogError
        Not a ZIP archive, or one holding no file or several (named, up to six)."""
    try:
        with zipfile.ZipFile(path) as archive:
            names = [info.filename for info in archive.infolist() if not info.is_dir()
                     and not info.filename.startswith("__MACOSX/") and not Path(info.filename).name.startswith(".")]
    except (zipfile.BadZipFile, OSError) as error:
        raise CompressedLogError(f"cannot read {path} as a ZIP archive: {error}") from None
    if len(names) != 1:
        shown = ", ".join(names[:6]) + (f" and {len(names) - 6} more" if len(names) > 6 else "")
        raise CompressedLogError(f"{path}: a ZIP archive holding {len(names)} files ({shown or 'none'}); the readers "
                                 "take one CSV file a ZIP archive: pack each log on its own, or unpack it first")
    return names[0]


#: the endings of a delimited text table read as a CSV file (its delimiter told from its lines: a tab, ``;``, ``|``,
#: spaces): a tab-separated export, a MATLAB ``writematrix``'s or NumPy ``savetxt``'s text file
TEXT_TABLES: tuple[str, ...] = (".csv", ".tsv", ".txt")


def data_suffix(path: str | os.PathLike[str]) -> str:
    """The format's ending of the table a file holds, lower case: its own (``.csv``, ``.parquet``; ``.csv`` for a
    delimited text table, :data:`TEXT_TABLES`), or for a packed file that of the file it packs (``.csv`` for
    ``run.csv.gz``, or for a ZIP archive holding ``run.csv``), CSV's where its name says no format (``run.gz``,
    ``run.txt.gz``)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in TEXT_TABLES:
        return ".csv"
    if suffix not in COMPRESSIONS:
        return suffix
    inner = Path(zip_member(path)).suffix.lower() if suffix == ".zip" and path.is_file() else \
        "" if suffix == ".zip" else Path(path.stem).suffix.lower()
    return ".csv" if inner in ("", *TEXT_TABLES) else inner


def packed_format(path: str | os.PathLike[str]) -> str:
    """The format a table file is read in: :func:`data_suffix`, a packed file's CSV whatever its inner name says
    when it says none (``run.gz``).

    Raises
    ------
    CompressedLogError
        A packed Parquet file (Parquet compresses its own columns: unpack it) or another inner format."""
    suffix = data_suffix(path)
    if not is_packed(path) or suffix == ".csv":
        return suffix
    raise CompressedLogError(f"{path}: a {COMPRESSIONS[Path(path).suffix.lower()]}-packed {suffix!r} file; the "
                             "readers unpack CSV files only (a Parquet file compresses its own columns): unpack it "
                             "first")


def zstandard_module(path: str | os.PathLike[str]):
    """The ``zstandard`` module that reads the zstd-packed file ``path``.

    Raises
    ------
    ZstdSupportError
        It is not importable: the message names the package (``pip install zstandard``, the project's ``zstd``
        extra) and the other route (unpack the file with ``zstd -d``)."""
    try:
        import zstandard
    except ImportError:
        raise ZstdSupportError(
            f"cannot read {path}: a zstd-packed file needs the {ZSTD_PACKAGE} package (pip install {ZSTD_PACKAGE}, "
            f"or pip install 'robot-oed[zstd]'), or unpack it first (zstd -d {Path(path).name}: its inner name "
            f"{Path(path).stem!r})") from None
    return zstandard


class _ZstdFrames(io.RawIOBase):
    """The bytes a zstd-packed file packs, decompressed frame after frame as they are read (memory: one read's
    output), a file ending inside a frame (truncated) or holding no frame a :class:`CompressedLogError`:
    ``zstandard``'s own stream reader returns a truncated file's bytes short without a word."""

    def __init__(self, raw: IO[bytes], path: Path, zstandard) -> None:
        self._raw, self._path, self._zstandard = raw, path, zstandard
        self._decompressor = zstandard.ZstdDecompressor()
        self._frame = self._decompressor.decompressobj()
        self._fed = False  # the current frame has been given bytes
        self._frames = 0  # frames ended
        self._pending = bytearray()
        self._ended = False

    def readable(self) -> bool:
        return True

    def _fill(self) -> None:
        while not self._pending and not self._ended:
            data = self._raw.read(ZSTD_READ)
            if not data:
                self._ended = True
                if self._fed or not self._frames:
                    raise CompressedLogError(f"cannot unpack {self._path}: it ends inside a zstd frame (a truncated "
                                             "or corrupt file?)" if self._fed else
                                             f"cannot unpack {self._path}: it holds no zstd frame (an empty file?)")
                return
            while data:
                try:
                    self._pending += self._frame.decompress(data)
                except self._zstandard.ZstdError as error:
                    raise CompressedLogError(f"cannot unpack {self._path}: {error} (a corrupt file?)") from None
                self._fed = True
                if not self._frame.eof:
                    break
                data = self._frame.unused_data  # the next frame's first bytes (zstd -c a b > ab.zst)
                self._frame, self._fed, self._frames = self._decompressor.decompressobj(), False, self._frames + 1

    def readinto(self, buffer) -> int:
        self._fill()
        size = min(len(buffer), len(self._pending))
        buffer[:size] = self._pending[:size]
        del self._pending[:size]
        return size


class _Unpacking(io.RawIOBase):
    """A decompressor's stream whose corrupt or truncated data raise :class:`CompressedLogError` (a
    ``ValueError``, which every reader already turns into its message) naming the file."""

    def __init__(self, stream: IO[bytes], path: Path) -> None:
        self._stream, self._path = stream, path

    def readable(self) -> bool:
        return True

    def readinto(self, buffer) -> int:
        try:
            data = self._stream.read(len(buffer))
        except UNPACKING_ERRORS as error:
            raise CompressedLogError(f"cannot unpack {self._path}: {error or type(error).__name__} (a truncated or "
                                     "corrupt file?)") from None
        buffer[:len(data)] = data
        return len(data)


@contextlib.contextmanager
def open_binary(path: str | os.PathLike[str]) -> Iterator[IO[bytes]]:
    """The bytes of the table a file holds, as a stream: the file's own, or those it packs, decompressed as they are
    read (memory: the decompressor's window, not the file)."""
    path = Path(path)
    suffix = path.suffix.lower()
    with contextlib.ExitStack() as stack:
        if suffix not in COMPRESSIONS:
            yield stack.enter_context(path.open("rb"))
            return
        if suffix == ".zip":
            archive = stack.enter_context(zipfile.ZipFile(path))
            inner = stack.enter_context(archive.open(zip_member(path)))
        elif suffix == ".zst":
            zstandard = zstandard_module(path)
            inner = stack.enter_context(_ZstdFrames(stack.enter_context(path.open("rb")), path, zstandard))
        else:
            opener = {".gz": gzip.open, ".bz2": bz2.open, ".xz": lzma.open}[suffix]
            inner = stack.enter_context(opener(path, "rb"))
        yield stack.enter_context(io.BufferedReader(_Unpacking(inner, path), buffer_size=1 << 16))


@contextlib.contextmanager
def open_text(path: str | os.PathLike[str], *, errors: str = "replace") -> Iterator[IO[str]]:
    """The text of the table a file holds (its first lines: the dialect, a units row), as :func:`open` gives a
    plain file's, a packed file's decompressed as it is read."""
    if not is_packed(path):
        with open(path, errors=errors) as stream:
            yield stream
        return
    with open_binary(path) as binary:
        yield io.TextIOWrapper(binary, errors=errors)


@contextlib.contextmanager
def csv_input(path: str | os.PathLike[str]) -> Iterator[str | os.PathLike[str] | IO[bytes]]:
    """What ``pandas.read_csv`` reads a CSV file from: a plain file's path (as before), a packed file's decompressed
    stream (:func:`open_binary`)."""
    if not is_packed(path):
        yield path
        return
    with open_binary(path) as stream:
        yield stream


def packer_named(path: str | os.PathLike[str]) -> str:
    """The unknown-format message's note on a file packed by a packer not read (:data:`OTHER_PACKERS`), ``""``
    otherwise."""
    path = Path(path)
    if path.suffix.lower() not in OTHER_PACKERS:
        return ""
    return (f"; a compressed file ({path.suffix}, not read: gzip, bzip2, xz, zstd and one-file ZIP archives are): "
            f"unpack it first (its inner name {path.stem!r})")
