"""Logs as they come, round five (h-logs5): a zstd-packed CSV file (read through ``zstandard`` where it is importable,
refused naming the package otherwise), an integer time count with a blank cell (one decision and one answer in
memory and streamed), and further forms other tools write.

The cheap tests read a PUMA's three joints' 2 s record at 250 Hz each way, in memory and block by block, against the
plain file's reading (:mod:`tests.test_packed_and_foreign_logs`' fixtures). The slow test runs the verbs on each
form against the plain fit."""

from __future__ import annotations

import sys
import warnings

import numpy as np
import pandas as pd
import pytest

from tests.test_packed_and_foreign_logs import held_to_the_plain_fit, plain, puma3, read_both  # noqa: F401  (fixtures)

zstandard = pytest.importorskip("zstandard", reason="the zstd extra (pip install zstandard) packs the zstd logs")


def zstd_packed(path, target, *, frames: int = 1):
    """``path`` packed by zstd into ``target`` in ``frames`` frames (``zstd -c a b > ab.zst`` writes two; the later
    ones without their size, as a stream's)."""
    raw = path.read_bytes()
    cuts = np.linspace(0, len(raw), frames + 1).astype(int)
    target.write_bytes(b"".join(zstandard.ZstdCompressor(write_content_size=index == 0).compress(raw[start:stop])
                                for index, (start, stop) in enumerate(zip(cuts[:-1], cuts[1:]))))
    return target


@pytest.mark.parametrize("frames", [1, 3])
def test_a_zstd_packed_csv_file_is_read_as_the_file_it_packs(puma3, plain, tmp_path, frames):  # noqa: F811
    """``train.csv.zst`` (one frame, or several as ``zstd -c`` of several files writes): read as the file it packs in
    memory and block by block (the same samples, exactly), its rows counted as the plain file's. At 2d5c469 it was
    refused ("a compressed file (.zst, not read …): unpack it first")."""
    from estimation.data.memory_budget import count_rows

    model, clean = puma3
    path = zstd_packed(clean, tmp_path / "train.csv.zst", frames=frames)
    memory, streamed, _ = read_both(path, model, chunk_size=150)
    for name in ("t", "q", "tau"):
        assert np.array_equal(getattr(memory, name), getattr(plain, name)), name
        assert np.array_equal(streamed[name], getattr(plain, name)), name
    assert count_rows(path) == count_rows(clean)


def test_a_zstd_file_cut_short_or_corrupt_is_named(puma3, tmp_path):  # noqa: F811
    """A truncated zstd file (``zstandard``'s own stream reader returns it short without a word), an empty one and a
    corrupt one: each a ``CompressedLogError`` naming the problem, in memory and streamed."""
    from estimation.data.compressed_logs import CompressedLogError
    from estimation.data.records import read_measurements
    from estimation.streaming.chunks import read_chunks

    model, clean = puma3
    whole = zstd_packed(clean, tmp_path / "whole.csv.zst").read_bytes()
    cases = {"cut.csv.zst": (whole[:-300], "ends inside a zstd frame"), "empty.csv.zst": (b"", "holds no zstd frame"),
             "bad.csv.zst": (whole[:4] + b"\x00" * 200, "cannot unpack .*bad.csv.zst")}
    for name, (data, said) in cases.items():
        (tmp_path / name).write_bytes(data)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with pytest.raises(CompressedLogError, match=said):
                read_measurements(tmp_path / name, model=model)
            with pytest.raises(CompressedLogError, match=said):
                list(read_chunks(tmp_path / name, model, chunk_size=100))


def test_without_zstandard_a_zstd_file_names_the_package_and_the_verb_exits_2(puma3, tmp_path, monkeypatch):  # noqa: F811
    """Where ``zstandard`` is not importable: a ``ZstdSupportError`` naming ``pip install zstandard`` (and the
    project's extra), in memory and streamed; ``oed identify`` exits with code 2 saying so, no traceback."""
    from estimation.data.compressed_logs import ZstdSupportError
    from estimation.data.records import read_measurements
    from estimation.streaming.chunks import read_chunks
    from tests.test_unseen_robot_kinds import quiet

    model, clean = puma3
    path = zstd_packed(clean, tmp_path / "train.csv.zst")
    monkeypatch.setitem(sys.modules, "zstandard", None)  # import zstandard raises ImportError
    said = r"needs the zstandard package \(pip install zstandard, or pip install 'robot-oed\[zstd\]'\)"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(ZstdSupportError, match=said):
            read_measurements(path, model=model)
        with pytest.raises(ZstdSupportError, match=said):
            list(read_chunks(path, model, chunk_size=100))
    code, message = quiet(["identify", "--robot", "puma560", "--joints", "3", "--data", str(path), "--out",
                           str(tmp_path / "result.json")])
    assert code == 2 and "Traceback" not in message and "pip install zstandard" in message, message


def counted(table: pd.DataFrame, how: str) -> pd.DataFrame:
    """``table`` with its time as integer counts: nanoseconds since 1970 (``ns``, odd nanoseconds added: a float
    rounds such a count to 256 ns) or microseconds since the start (``us``)."""
    table = table.copy()
    if how == "ns":
        table["t"] = 1_732_000_000_000_000_001 + np.round(table["t"].to_numpy() * 1e9).astype(np.int64)
    else:
        table["t"] = np.round(table["t"].to_numpy() * 1e6).astype(np.int64)
    return table


def with_blanks(table: pd.DataFrame, rows: list[int], columns=None) -> pd.DataFrame:
    """``table`` with the cells of ``rows`` (every column, or ``columns``) left blank."""
    table = table.astype(object)
    table.loc[rows, list(table.columns) if columns is None else columns] = None
    return table


@pytest.mark.parametrize("how", ["ns", "us"])
def test_an_integer_count_with_a_blank_row_is_read_alike_in_memory_and_streamed(puma3, tmp_path, how):  # noqa: F811
    """Integer stamps (ns since 1970, us since the start) with rows left blank, one in the streamed reader's first
    block and one in a later block: both readers drop them as the dropouts they are, as they drop them from the same
    file with the time in seconds; the stamps the seconds file's (1e-12 s), the samples too (1e-9 relative: the
    stall the blank row leaves is bridged at those stamps), streamed as in memory (1e-12). At 2d5c469
    memory parsed the column as floats and refused it ("advances by 4e+06 a sample"), the streamed reader read it
    (rounding the later blocks' nanosecond counts to 256 ns)."""
    model, clean = puma3
    table = pd.read_csv(clean)
    rows = [40, 310]
    with_blanks(table, rows).to_csv(tmp_path / "seconds.csv", index=False, float_format="%.17g")
    with_blanks(counted(table, how), rows).to_csv(tmp_path / "counted.csv", index=False, float_format="%.17g")
    reference, _, _ = read_both(tmp_path / "seconds.csv", model, chunk_size=100)
    memory, streamed, said = read_both(tmp_path / "counted.csv", model, chunk_size=100)
    assert sum("holds integer counts" in text for text in said) >= 2, said
    assert np.allclose(memory.t, reference.t - reference.t[0], rtol=0, atol=1e-12)
    assert np.array_equal(streamed["t"], memory.t)
    for name in ("q", "tau"):
        assert np.allclose(getattr(memory, name), getattr(reference, name), rtol=1e-9, atol=1e-12), name
        assert np.allclose(streamed[name], getattr(memory, name), rtol=1e-12, atol=1e-15), name  # an ulp at a
        # block's edge where the stamps, counted in us, fall off the grid by one (the resampler's, as for any file)


def test_an_integer_count_missing_one_stamp_is_refused_alike(puma3, tmp_path):  # noqa: F811
    """A row with its data but no stamp (an integer count's cell left blank): refused by both readers naming the
    cell, as the same row is with the time in seconds; a count written with a decimal further on (not an integer
    throughout) refused by the streamed reader naming the row."""
    from estimation.data import MeasurementError, NonFiniteError
    from estimation.data.records import read_measurements
    from estimation.streaming.chunks import read_chunks

    model, clean = puma3
    table = counted(pd.read_csv(clean), "ns")
    with_blanks(table, [310], ["t"]).to_csv(tmp_path / "stampless.csv", index=False)
    mixed = table.astype(object)
    mixed.loc[320, "t"] = f"{mixed.loc[320, 't']}.5"
    mixed.to_csv(tmp_path / "mixed.csv", index=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(NonFiniteError, match="column t holds 1 NaN"):
            read_measurements(tmp_path / "stampless.csv", model=model)
        with pytest.raises(NonFiniteError, match="column t holds 1 NaN"):
            list(read_chunks(tmp_path / "stampless.csv", model, chunk_size=100))
        with pytest.raises(MeasurementError, match=r"holds integer counts in its first rows and '1732.*\.5', not an "
                                                   "integer, at row 320"):
            list(read_chunks(tmp_path / "mixed.csv", model, chunk_size=100))


def _text(table: pd.DataFrame, **options) -> str:
    return table.to_csv(index=False, float_format="%.17g", **options)


def _instants(table: pd.DataFrame, form: str) -> pd.Series:
    stamps = pd.Timestamp("2026-11-28 10:00:00") + pd.to_timedelta(np.round(table["t"] * 1e9).astype(np.int64),
                                                                      unit="ns")
    return stamps.dt.strftime(form)


def numpy_savetxt(table, folder):
    """NumPy's ``savetxt(header=…)`` of a ``.txt`` file: ``# t q1 …`` above numbers separated by a space."""
    path = folder / "log.txt"
    np.savetxt(path, table.to_numpy(), header=" ".join(table.columns), fmt="%.17g")
    return path


def tab_separated(table, folder):
    """A ``.tsv`` export (a tab between the fields)."""
    path = folder / "log.tsv"
    path.write_text(_text(table, sep="\t"))
    return path


def notes_above_the_header(table, folder):
    """A logger's notes above its header (``# robot: …``, ``# rate: 250 Hz``)."""
    path = folder / "log.csv"
    path.write_text("# robot: puma560, 3 joints\n# rate: 250 Hz\n# started 2026-11-28 10:00:00\n" + _text(table))
    return path


def logging_date_times(table, folder):
    """Date-times as Python's ``logging`` writes them (``2026-11-28 10:00:00,004``: a comma before the fraction)."""
    path = folder / "log.csv"
    path.write_text(_text(table.assign(t=_instants(table, "%Y-%m-%d %H:%M:%S,%f"))))
    return path


def european_date_times(table, folder):
    """A European spreadsheet's export (``;``, decimal commas) whose time is ISO date-times with a point before the
    fraction (its point no decimal mark)."""
    path = folder / "log.csv"
    path.write_text(_text(table.assign(t=_instants(table, "%Y-%m-%d %H:%M:%S.%f")), sep=";", decimal=","))
    return path


FORMS = {"numpy savetxt .txt": numpy_savetxt, ".tsv": tab_separated, "notes above the header": notes_above_the_header,
         "logging's date-times": logging_date_times, "European date-times": european_date_times}


@pytest.mark.parametrize("form", list(FORMS))
def test_further_forms_are_read_as_the_plain_file_in_memory_and_streamed(puma3, plain, tmp_path, form):  # noqa: F811
    """Each form read in memory and block by block to the plain file's samples (the stamps to 1e-9 s, the samples to
    1e-12 relative: ``%.17g`` writes each float exactly, so they are equal), said in a warning. At 2d5c469 every one
    was refused on both paths: ``.txt`` and ``.tsv`` ("unknown data format"), the notes ("Error tokenizing data"),
    logging's date-times ("row 0 holds text in every column"), the European date-times ("the columns are separated
    by ';'")."""
    model, clean = puma3
    path = FORMS[form](pd.read_csv(clean), tmp_path)
    memory, streamed, said = read_both(path, model, chunk_size=150)
    assert said, form
    for reading in (memory, streamed):
        t = reading.t if reading is memory else reading["t"]
        assert len(t) == len(plain.t) and np.allclose(t - t[0], plain.t - plain.t[0], rtol=0, atol=1e-9), said
        for name in ("q", "tau"):
            values = getattr(reading, name) if reading is memory else reading[name]
            assert np.allclose(values, getattr(plain, name), rtol=1e-12, atol=0), (name, said)


def zstd_log(table, folder):
    path = folder / "plain.csv"
    path.write_text(_text(table))
    return zstd_packed(path, folder / "log.csv.zst")


def nanoseconds_with_blank_rows(table, folder):
    """Nanoseconds since 1970 with two rows left blank (a logger's dropouts)."""
    path = folder / "log.csv"
    rows = [len(table) // 7, len(table) // 2]
    with_blanks(counted(table, "ns"), rows).to_csv(path, index=False, float_format="%.17g")
    return path


VERB_FORMS = {"zstd": zstd_log, "ns with blank rows": nanoseconds_with_blank_rows, **FORMS}


@pytest.mark.slow
@pytest.mark.parametrize("streamed", [False, True], ids=["in memory", "streamed"])
@pytest.mark.parametrize("form", list(VERB_FORMS))
def test_the_verbs_read_each_form_and_predict_as_well_as_a_plain_fit(form, streamed, tmp_path):
    """The default ``oed identify`` (told the plain class) and ``oed diagnose`` on a PUMA 3's records (8 s / 3 s /
    5 s at 250 Hz, no dq) written in the form, in memory or streamed (``--chunk-size 300``), then ``oed predict`` on
    the test record (written alike): within the plain fit's figures (total at most 1.0x, each joint 1.3x), the
    validation error reproduced (1e-6); as ``tests/test_packed_and_foreign_logs.py`` runs the habits of h-logs4."""
    from benchmarks.bench_real_robots import PlainFit
    from tests.test_unseen_robot_labs import Lab, puma, verbs_against_the_plain_fit, write_records
    from tests.test_unseen_robots import Log

    lab = Lab("PUMA 3", puma(3), Log(8.0, 250.0, velocity=False), Log(3.0, 250.0, velocity=False),
              Log(5.0, 250.0, velocity=False))
    urdf, records, files, _ = write_records(lab, tmp_path)
    plain_fit = PlainFit(["--urdf", str(urdf)])
    cutoff, theta = plain_fit.fit(records["train"], records["validate"], rate_hz=250.0)
    predicted, kept = plain_fit.predict(records["test"], cutoff, theta)
    written = {}
    for role, path in files.items():
        folder = tmp_path / f"form_{role}"
        folder.mkdir()
        written[role] = VERB_FORMS[form](pd.read_csv(path), folder)
    outcome = verbs_against_the_plain_fit(urdf, written, records["test"], kept, predicted, tmp_path,
                                          options=("--chunk-size", "300") if streamed else ())
    held_to_the_plain_fit(outcome, form, streamed)
