"""Benchmark (issue 34): the four real robots' logs degraded as a user's would be, the default ``oed identify`` and
``oed diagnose`` (then ``oed predict``) against the plain least-squares fit on the same degraded records.

The records are those of :mod:`benchmarks.bench_real_robots` (training, validation, test per robot, the files the
toolkit reads). Each degradation changes the files as a user's logger or a user's hands would; the plain fit reads
the same degraded files (:func:`record_of`: joint-side time, positions, torques, the rows a user's reader would
keep), and every model is scored on the degraded test record's recorded samples (:func:`compare_degraded`).

Degradations (:data:`DEGRADATIONS`), each applied to every record a role holds unless said otherwise:

``short``
    the training record cut to its first third, the validation record to its first 2 s;
``100 Hz`` / ``50 Hz``
    every k-th row kept (no anti-alias filter: a logger polling at a lower rate);
``jitter``
    each time stamp moved by a uniform error of at most 40 % of its smaller gap to a neighbour (the samples where
    they were, the stamps' order kept);
``dropped``
    1 % of the rows removed at random;
``stall``
    five stalls of 20 ms: the row before each repeated (values frozen, stamps advancing);
``NaN rows``
    0.5 % of the rows' values blank (the time stamp written);
``units header``
    a second header line of units (``s``, ``rad``, ``N m``) under the column names;
``torque offset``
    the torque of the robot's first joint (on EMPS its force) plus a constant of 20 % of its spread, every record;
``torque gain``
    the same channel times 1.1 (a sensor's gain error), every record;
``position offset``
    the first joint's position plus 0.05 rad (0.005 m on EMPS; a zero moved), every record;
``no validation``
    no ``--validate`` (the plain fit still chooses its cut-off on the validation record: a stricter yardstick);
``validation = training``
    the training file given again as ``--validate`` (the plain fit chooses its cut-off on it too).

Per degradation and robot: the verbs' exit (and message), the test MSE per joint of each verb over the plain fit's
on the same samples, and ``oed predict``'s reproduction of the error each verb reported (``identify``: the chosen
model's validation error, predicted on the validation file; ``diagnose`` run with ``--test``: its chosen model's
test error, predicted on the test file; relative).

Run: ``python benchmarks/bench_real_degraded.py [--robots kuka,panda,tx40,emps] [--degradations short,jitter,...]
[--markdown table.md]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.bench_real_robots import (DATA, FRICTION, ROBOTS, TX40_RATIOS, Case, PlainFit, Record, at_recorded,
                                          resent, tx40_transmission)

Frames = dict[str, pd.DataFrame]
#: relative agreement asked of ``oed predict`` with the error a verb reported
RELATIVE = 1e-6


def _every(frames: Frames, rate_hz: float) -> Frames:
    out = {}
    for role, frame in frames.items():
        step = float(np.median(np.diff(frame["t"].to_numpy())))
        k = max(1, int(round(1.0 / (rate_hz * step))))
        out[role] = frame.iloc[::k].reset_index(drop=True)
    return out


def _short(frames: Frames) -> Frames:
    train, validate = frames["train"], frames["validate"]
    return {**frames, "train": train.iloc[: train.shape[0] // 3].reset_index(drop=True),
            "validate": validate[validate["t"] < validate["t"].iloc[0] + 2.0].reset_index(drop=True)}


def _jitter(frames: Frames, generator: np.random.Generator) -> Frames:
    out = {}
    for role, frame in frames.items():
        t = frame["t"].to_numpy()
        gaps = np.diff(t)
        room = np.minimum(np.r_[gaps[0], gaps], np.r_[gaps, gaps[-1]])  # the order of the stamps kept
        frame = frame.copy()
        frame["t"] = t + generator.uniform(-0.4, 0.4, frame.shape[0]) * room
        out[role] = frame
    return out


def _dropped(frames: Frames, generator: np.random.Generator) -> Frames:
    out = {}
    for role, frame in frames.items():
        n = frame.shape[0]
        lost = generator.choice(np.arange(1, n - 1), max(1, n // 100), replace=False)
        out[role] = frame.drop(index=lost).reset_index(drop=True)
    return out


def _stall(frames: Frames, generator: np.random.Generator) -> Frames:
    out = {}
    for role, frame in frames.items():
        frame = frame.copy()
        t = frame["t"].to_numpy()
        step = float(np.median(np.diff(t)))
        length = max(1, int(round(0.020 / step)))
        values = [c for c in frame.columns if c != "t"]
        starts = generator.choice(np.arange(10, frame.shape[0] - length - 10), 5, replace=False)
        for start in starts:
            frame.loc[start + 1: start + length, values] = frame.loc[start, values].to_numpy()
        out[role] = frame
    return out


def _nan_rows(frames: Frames, generator: np.random.Generator) -> Frames:
    out = {}
    for role, frame in frames.items():
        frame = frame.copy()
        n = frame.shape[0]
        blank = generator.choice(np.arange(5, n - 5), max(1, n // 200), replace=False)
        frame.loc[blank, [c for c in frame.columns if c != "t"]] = np.nan
        out[role] = frame
    return out


def _torque_column(frame: pd.DataFrame) -> str:
    return "taum1" if "taum1" in frame.columns else "tau1"


def _position_column(frame: pd.DataFrame) -> str:
    return "qm1" if "qm1" in frame.columns else "q1"


def _torque_offset(frames: Frames) -> Frames:
    column = _torque_column(frames["train"])
    shift = 0.2 * float(frames["train"][column].std())
    return {role: frame.assign(**{column: frame[column] + shift}) for role, frame in frames.items()}


def _torque_gain(frames: Frames) -> Frames:
    column = _torque_column(frames["train"])
    return {role: frame.assign(**{column: frame[column] * 1.1}) for role, frame in frames.items()}


def _position_offset(frames: Frames, prismatic: bool) -> Frames:
    column = _position_column(frames["train"])
    shift = 0.005 if prismatic else 0.05
    if column == "qm1":  # the TX40's motor side: the joint's zero moved, seen through the gear
        shift *= TX40_RATIOS[0]
    return {role: frame.assign(**{column: frame[column] + shift}) for role, frame in frames.items()}


#: name: (what it does to the frames, given the frames, a generator and whether the robot is prismatic),
#: and how the verbs are told of the validation record ("given", "none", "training")
DEGRADATIONS: dict[str, tuple[Callable[[Frames, np.random.Generator, bool], Frames], str]] = {
    "short": (lambda f, g, p: _short(f), "given"),
    "100 Hz": (lambda f, g, p: _every(f, 100.0), "given"),
    "50 Hz": (lambda f, g, p: _every(f, 50.0), "given"),
    "jitter": (lambda f, g, p: _jitter(f, g), "given"),
    "dropped": (lambda f, g, p: _dropped(f, g), "given"),
    "stall": (lambda f, g, p: _stall(f, g), "given"),
    "NaN rows": (lambda f, g, p: _nan_rows(f, g), "given"),
    "units header": (lambda f, g, p: f, "given"),
    "torque offset": (lambda f, g, p: _torque_offset(f), "given"),
    "torque gain": (lambda f, g, p: _torque_gain(f), "given"),
    "position offset": (lambda f, g, p: _position_offset(f, p), "given"),
    "no validation": (lambda f, g, p: f, "none"),
    "validation = training": (lambda f, g, p: f, "training"),
}


def _unit(column: str) -> str:
    if column == "t":
        return "s"
    if column.startswith("tau"):
        return "N m"
    if column.startswith(("ddq", "dq")):
        return "rad/s^2" if column.startswith("ddq") else "rad/s"
    return "rad"


def write_frame(frame: pd.DataFrame, path: Path, *, units: bool = False) -> Path:
    """The CSV a user's logger writes; with ``units`` a second header line naming each column's unit."""
    with path.open("w") as stream:
        stream.write(",".join(frame.columns) + "\n")
        if units:
            stream.write(",".join(_unit(column) for column in frame.columns) + "\n")
        frame.to_csv(stream, index=False, header=False, float_format="%.10g")
    return path


def record_of(frame: pd.DataFrame) -> Record:
    """Joint-side time, positions, torques (and the logged velocity) of a record as written, the rows with a blank
    value left out (what the plain fit reads; the TX40's motor side mapped through its transmission)."""
    frame = frame.dropna().reset_index(drop=True)
    t = frame["t"].to_numpy(float)
    if "qm1" in frame.columns:  # the TX40: motor side
        matrix = tx40_transmission()
        qm = frame[[f"qm{j + 1}" for j in range(6)]].to_numpy(float)
        taum = frame[[f"taum{j + 1}" for j in range(6)]].to_numpy(float)
        return Record(t, np.linalg.solve(matrix, qm.T).T, taum @ matrix)
    n = sum(1 for c in frame.columns if c.startswith("q") and c[1:].isdigit())
    q = frame[[f"q{j + 1}" for j in range(n)]].to_numpy(float)
    tau = frame[[f"tau{j + 1}" for j in range(n)]].to_numpy(float)
    dq = frame[[f"dq{j + 1}" for j in range(n)]].to_numpy(float) if "dq1" in frame.columns else None
    return Record(t, q, tau, dq)


def degraded_case(key: str, degradation: str, folder: Path, seed: int = 0) -> tuple[Case, str]:
    """The robot ``key``'s case with its files degraded by ``degradation``, and how the validation is given."""
    folder.mkdir(parents=True, exist_ok=True)
    case = ROBOTS[key](folder)
    change, validation = DEGRADATIONS[degradation]
    frames = {role: pd.read_csv(path) for role, path in case.files.items()}
    frames = change(frames, np.random.default_rng(seed), key == "emps")
    for role, frame in frames.items():
        case.files[role] = write_frame(frame, folder / f"{key}_{role}_degraded.csv",
                                       units=degradation == "units header")
        case.records[role] = record_of(frame)
    return case, validation


def _relative(measured: dict, reported: dict) -> float:
    return max(abs(measured[channel] / reported[channel] - 1) for channel in reported)


def _reported_validation(document: dict) -> dict | None:
    """The chosen model's reported validation error (``identify``'s result.json), if it reports one."""
    validation = document.get("validation") or {}
    if "chosen" in validation:
        return validation["chosen"].get("mse")
    return validation.get("mse")


def run_verb(case: Case, validation: str, verb: str, folder: Path) -> dict:
    """The default ``verb`` on the degraded case, then ``oed predict`` on the test file (and, for ``identify``, on
    the validation file): ``{exit, message, t, predicted, reproduced, chosen, effects, seconds}``."""
    result = folder / f"{verb}.json"
    given = {"given": ["--validate", str(case.files["validate"])], "none": [],
             "training": ["--validate", str(case.files["train"])]}[validation]
    more = ["--friction", FRICTION] if verb == "identify" else ["--test", str(case.files["test"])]
    started = time.perf_counter()
    code, _, message = run_logged([verb, *case.robot, *case.options, "--data", str(case.files["train"]), *given, *more,
                                   "--out", str(result)])
    seconds = time.perf_counter() - started
    if code != 0:
        return {"exit": code, "message": message, "seconds": seconds}
    document = json.loads(result.read_text())
    out, metrics = folder / f"{verb}_test.csv", folder / f"{verb}_test.json"
    code, _, message = run_logged(["predict", "--model", str(result), "--data", str(case.files["test"]), "--out",
                                   str(out), "--metrics", str(metrics)])
    if code != 0:
        return {"exit": code, "message": f"oed predict: {message}", "seconds": seconds}
    reproduced = None
    if verb == "diagnose" and document.get("test") and document["test"].get("chosen"):
        reproduced = _relative(json.loads(metrics.read_text())["mse"], document["test"]["chosen"]["mse"])
    elif verb == "identify" and validation != "none" and _reported_validation(document):
        validate_metrics = folder / f"{verb}_validate.json"
        code, _, message = run_logged(["predict", "--model", str(result), "--data", given[1], "--out",
                                       str(folder / f"{verb}_validate.csv"), "--metrics", str(validate_metrics)])
        if code != 0:
            return {"exit": code, "message": f"oed predict (validation): {message}", "seconds": seconds}
        reproduced = _relative(json.loads(validate_metrics.read_text())["mse"], _reported_validation(document))
    table = pd.read_csv(out)
    channels = [column for column in table.columns if column.startswith("tau") and column[3:].isdigit()]
    return {"exit": 0, "message": "", "t": table["t"].to_numpy(), "predicted": table[channels].to_numpy(),
            "reproduced": reproduced, "chosen": chosen_text(document.get("model_selection") or {}),
            "effects": [f"{e['spec']} on {','.join(e['channels'])}" for e in document.get("effects", [])
                        if isinstance(e, dict)], "seconds": seconds}


def chosen_text(selection: dict) -> str | None:
    """The chosen model, and when the best-scoring one was compared with the consistent one on the same validation
    samples (``paired_difference``), that difference ± its standard error."""
    paired = selection.get("paired_difference")
    if not paired:
        return selection.get("chosen")
    return (f"{selection.get('chosen')} ({paired['regularised']} − {paired['best']} {paired['difference']:.3g} ± "
            f"{paired['standard_error']:.2g})")


def run_logged(arguments: list[str]) -> tuple[int, str, str]:
    """``oed ARGUMENTS`` quietly: ``(exit code, stdout, the last lines of stderr)``."""
    import contextlib
    import io

    from oed.cli import main

    with contextlib.redirect_stdout(io.StringIO()) as out, contextlib.redirect_stderr(io.StringIO()) as err:
        try:
            code = main(arguments)
        except SystemExit as stop:  # the parser's own refusal (a required option missing)
            code = stop.code if isinstance(stop.code, int) else 2
    return code, out.getvalue(), err.getvalue().strip()[-600:]


def compare_degraded(key: str, degradation: str, folder: Path, verbs: tuple[str, ...] = ("identify", "diagnose")
                     ) -> dict:
    """Per verb: its exit, the test MSE per joint of its prediction and of the plain fit at the same recorded samples
    (those both predict, beyond the plain filter's settling, not re-sent rows), the reproduction of its reported
    error, its chosen model and effects."""
    case, validation = degraded_case(key, degradation, folder)
    plain = PlainFit(case.robot)
    validate = case.records["train"] if validation == "training" else case.records["validate"]
    cutoff, theta = plain.fit(case.records["train"], validate)
    test = case.records["test"]
    predicted_plain, kept = plain.predict(test, cutoff, theta)
    outcome = {"cutoff": cutoff, "verbs": {}}
    for verb in verbs:
        run = run_verb(case, validation, verb, folder)
        if run["exit"] == 0:
            rows, values = at_recorded(test.t, run["t"], run["predicted"])
            use = kept[rows] & ~resent(test)[rows]
            rows, values = rows[use], values[use]
            run["mse"] = np.mean((test.tau[rows] - values) ** 2, axis=0)
            run["plain"] = np.mean((test.tau[rows] - predicted_plain[rows]) ** 2, axis=0)
            run["samples"] = rows.shape[0]
        for heavy in ("t", "predicted"):
            run.pop(heavy, None)
        outcome["verbs"][verb] = run
    return outcome


def line(robot: str, degradation: str, outcome: dict) -> list[str]:
    """Table rows: robot, degradation, verb, total / plain, mean joint / plain, worst joint / plain, reproduced,
    chosen, seconds (or the exit and its message)."""
    rows = []
    for verb, run in outcome["verbs"].items():
        if run["exit"] != 0:
            last = [text for text in run["message"].splitlines() if text.strip()][-1:] or [""]
            message = " ".join(last[0].split())[-200:].replace("|", "/")
            rows.append(f"| {robot} | {degradation} | {verb} | **exit {run['exit']}** | – | – | – | – | {message} |")
            continue
        ratio = run["mse"] / run["plain"]
        reproduced = "–" if run["reproduced"] is None else f"{run['reproduced']:.1e}"
        rows.append(f"| {robot} | {degradation} | {verb} | {run['mse'].sum() / run['plain'].sum():.3f} | "
                    f"{ratio.mean():.3f} | {ratio.max():.3f} (j{ratio.argmax() + 1}) | {reproduced} | "
                    f"{run['chosen']} | {outcome['cutoff']:g} Hz plain; {run['seconds']:.0f} s |")
    return rows


HEADER = ["| robot | degradation | verb | total / plain | mean joint / plain | worst joint / plain | predict reproduces "
          "(relative) | chosen | notes |", "|---|---|---|---|---|---|---|---|---|"]


def main_benchmark() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="kuka,panda,tx40,emps")
    parser.add_argument("--degradations", default=",".join(DEGRADATIONS), help="comma-separated (default: all)")
    parser.add_argument("--verbs", default="identify,diagnose")
    parser.add_argument("--markdown", type=Path, help="append the table's rows to this file too")
    args = parser.parse_args()
    if not DATA.is_dir():
        sys.exit(f"no real data at {DATA}")
    print("\n".join(HEADER), flush=True)
    for key in args.robots.split(","):
        for degradation in args.degradations.split(","):
            with tempfile.TemporaryDirectory() as folder:
                outcome = compare_degraded(key, degradation, Path(folder), tuple(args.verbs.split(",")))
            rows = line(key, degradation, outcome)
            print("\n".join(rows), flush=True)
            if args.markdown is not None:
                with args.markdown.open("a") as stream:
                    stream.write("\n".join(rows) + "\n")


if __name__ == "__main__":
    main_benchmark()
