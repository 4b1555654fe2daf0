"""Benchmark (issue 34): a robustness sweep of the defaults over the real logs of ``../shared/data`` in
configurations :mod:`bench_real_robots` does not use, as a new user would try them.

Each configuration writes its training / validation / test records as files (in a temporary folder: no data
enters the repository), then runs, through the command line in a subprocess (exit codes and messages matter):

``identify``
    ``oed identify --data TRAIN [--validate VALIDATE] --friction viscous,coulomb,offset --out R.json``
    (nothing else), then ``oed predict --model R.json --data TEST``;
``diagnose``
    ``oed diagnose --data TRAIN [--validate VALIDATE] --out D.json`` (its own defaults), then ``oed predict``.

Each is compared, per joint, with the benchmark's plain least-squares fit
(:class:`bench_real_robots.PlainFit`: rigid body + viscous + Coulomb + offset per joint, zero-phase filtered
derivatives, the cut-off chosen on the validation record, or on the training record when the configuration has
none) on the test record, at the recorded samples that every model predicted. A run that exits prints its exit
code and the last line of its message; a bare Python traceback is flagged (``TRACEBACK``): it is a bug.

Run: ``PYTHONPATH=. python benchmarks/bench_sweep.py [--only NAME,NAME] [--list] [--markdown table.md]`` (one
configuration at a time; the whole sweep takes tens of minutes).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_real_robots import (  # noqa: E402
    DATA,
    FRICTION,
    TX40_RATIOS,
    TX40_ZERO,
    PlainFit,
    Record,
    at_recorded,
    tx40_transmission,
)

from estimation.datasets.kuka import load_kuka_run  # noqa: E402
from estimation.datasets.shared import load_emps  # noqa: E402


@dataclass
class Logged(Record):
    """A record with the logged acceleration, when the log has one."""

    ddq: np.ndarray | None = None


@dataclass
class Log:
    """One robot's raw material: the records by name, what the toolkit is told about the robot, and how a record
    is written for the toolkit (``layout``: column order and extra columns)."""

    robot: list[str]
    records: dict[str, Record]
    options: list[str] = field(default_factory=list)
    motor_side: bool = False  # TX40: write motor-side qm/taum


def _slice(record: Record, start: float, stop: float) -> Record:
    return _rows(record, np.flatnonzero((record.t >= start) & (record.t < stop)))


def kuka_log() -> Log:
    source = DATA / "kuka_lwr4"
    log = Log(["--urdf", str(source / "kuka_lwr4.urdf")], {})
    for index in (1, 2, 3):
        run = load_kuka_run(source / f"kuka_lwr4_HW_measurements_{index}.npz")
        log.records[f"run{index}"] = Logged(run.t, run.q, run.tau, run.dq, run.ddq)
    return log


def panda_log() -> Log:
    source = DATA / "panda"
    folder = source / "Trajectory_1" / "rbt_log"
    t = np.loadtxt(folder / "exciting_traj_time.txt").reshape(-1)
    q, dq, tau = (np.loadtxt(folder / f"exciting_traj_{name}.txt").reshape(-1, 7)
                  for name in ("positions", "velocity", "torques"))
    return Log(["--urdf", str(source / "panda_gaz.urdf")], {"log": Logged(t, q, tau, dq)})


def tx40_log(folder: Path) -> Log:
    source = DATA / "tx40"
    qm = pd.read_csv(source / "pos_read_data.csv").to_numpy(dtype=float)
    taum = pd.read_csv(source / "curr_data.csv").to_numpy(dtype=float)
    t = np.arange(qm.shape[0]) * 0.0002
    matrix = tx40_transmission()
    q = np.linalg.solve(matrix, (qm + TX40_ZERO * TX40_RATIOS).T).T
    transmission = folder / "tx40_transmission.json"
    transmission.write_text(json.dumps({"ratios": TX40_RATIOS.tolist(), "couplings": {"6": {"5": TX40_RATIOS[5]}}}))
    return Log(["--urdf", str(source / "tx40_mdh_modified.urdf")], {"log": Logged(t, q, taum @ matrix)},
               options=["--transmission", str(transmission)], motor_side=True)


def emps_log() -> Log:
    source = DATA / "emps"
    records = {}
    for name, role in (("estimation", "estimation"), ("pulses", "validation")):
        data = load_emps(source, role)
        records[name] = Logged(data.t, data.qm[:, None], data.force[:, None])
    return Log(["--robot", "emps"], records)


# --- record transformations (what a user's log may look like) -------------------------------------------------

def _rows(record: Record, index: np.ndarray) -> Record:
    """The rows ``index`` of ``record`` (its logged acceleration too)."""
    return replace(record, t=record.t[index], q=record.q[index], tau=record.tau[index],
                   dq=None if record.dq is None else record.dq[index],
                   ddq=None if record.ddq is None else record.ddq[index])


def subsample(every: int) -> Callable[[Record], Record]:
    def apply(record: Record) -> Record:
        return _rows(record, np.arange(0, record.t.shape[0], every))
    return apply


def positions_only(record: Record) -> Record:
    return replace(record, dq=None, ddq=None)


def stamp_defects(record: Record, seed: int = 0) -> Record:
    """A few time stamps repeated (the row sent twice) and a few rows dropped, as a logger does."""
    generator = np.random.default_rng(seed)
    n = record.t.shape[0]
    drop = generator.choice(np.arange(10, n - 10), size=5, replace=False)
    repeat = generator.choice(np.arange(10, n - 10), size=5, replace=False)
    return _rows(record, np.sort(np.r_[np.setdiff1d(np.arange(n), drop), repeat]))


def hole(seconds: float, after: float | None = None) -> Callable[[Record], Record]:
    """The rows of ``seconds`` lost (a logger's stall longer than the default ``--max-gap``), in the middle of the
    record or ``after`` seconds from its start."""
    def apply(record: Record) -> Record:
        start = 0.5 * (record.t[-1] - record.t[0]) - 0.5 * seconds if after is None else after
        lost = (record.t - record.t[0] >= start) & (record.t - record.t[0] < start + seconds)
        return _rows(record, np.flatnonzero(~lost))
    return apply


def repeated_stamps(record: Record, seed: int = 1) -> Record:
    """Ten time stamps repeated with new values (a logger's clock that did not tick)."""
    generator = np.random.default_rng(seed)
    t = record.t.copy()
    for k in generator.choice(np.arange(10, t.shape[0] - 10), size=10, replace=False):
        t[k] = t[k - 1]
    return replace(record, t=t)


def epoch(record: Record) -> Record:
    """Time stamps in seconds since 1970 (a ROS log's clock), as a user exports them."""
    return replace(record, t=record.t + 1.7e9)


@dataclass
class Config:
    name: str
    robot: str  # kuka, panda, tx40, emps
    roles: dict[str, tuple[str, float, float]]  # role -> (record, start, stop); validate may be absent
    transform: Callable[[Record], Record] | dict[str, Callable[[Record], Record]] | None = None  # or by role
    layout: str = "plain"  # plain | shuffled (columns reordered, extra columns)
    note: str = ""


INF = np.inf
CONFIGS = [
    Config("kuka-312", "kuka", {"train": ("run3", 0, INF), "validate": ("run1", 0, INF), "test": ("run2", 0, INF)},
           note="KUKA train run 3, validate run 1, test run 2"),
    Config("kuka-231", "kuka", {"train": ("run2", 0, INF), "validate": ("run3", 0, INF), "test": ("run1", 0, INF)},
           note="KUKA train run 2, validate run 3, test run 1"),
    Config("kuka-noval", "kuka", {"train": ("run1", 0, INF), "test": ("run3", 0, INF)},
           note="KUKA train run 1, no validation, test run 3"),
    Config("kuka-posonly", "kuka", {"train": ("run1", 0, INF), "validate": ("run2", 0, INF),
                                    "test": ("run3", 0, INF)}, transform=positions_only,
           note="KUKA 1/2/3, positions only (no dq, ddq)"),
    Config("kuka-sub5", "kuka", {"train": ("run1", 0, INF), "validate": ("run2", 0, INF), "test": ("run3", 0, INF)},
           transform=subsample(5), note="KUKA 1/2/3, every 5th sample (40 Hz)"),
    Config("kuka-shortval", "kuka", {"train": ("run1", 0, INF), "validate": ("run2", 10.0, 11.5),
                                     "test": ("run3", 0, INF)}, note="KUKA 1/2/3, validation 1.5 s of run 2"),
    Config("kuka-shuffled", "kuka", {"train": ("run1", 0, INF), "validate": ("run2", 0, INF),
                                     "test": ("run3", 0, INF)}, layout="shuffled",
           note="KUKA 1/2/3, columns in another order and extra columns"),
    Config("kuka-gapval", "kuka", {"train": ("run1", 0, INF), "validate": ("run2", 0, INF), "test": ("run3", 0, INF)},
           transform=hole(0.1), note="KUKA 1/2/3, 0.1 s of rows lost in the middle of every record"),
    Config("kuka-edgehole", "kuka", {"train": ("run1", 0, INF), "validate": ("run2", 0, INF),
                                     "test": ("run3", 0, INF)}, transform=hole(0.1, after=0.3),
           note="KUKA 1/2/3, 0.1 s of rows lost 0.3 s after the start of every record"),
    Config("kuka-val05", "kuka", {"train": ("run1", 0, INF), "validate": ("run2", 10.0, 10.5),
                                  "test": ("run3", 0, INF)}, note="KUKA 1/2/3, validation 0.5 s of run 2"),
    Config("kuka-posonly-val1", "kuka", {"train": ("run1", 0, INF), "validate": ("run2", 10.0, 11.0),
                                         "test": ("run3", 0, INF)}, transform=positions_only,
           note="KUKA 1/2/3, positions only, validation 1 s of run 2"),
    Config("panda-posonly-val1", "panda", {"train": ("log", 0, 13.84), "validate": ("log", 13.84, 14.84),
                                           "test": ("log", 17.2, INF)}, transform=positions_only,
           note="Panda, positions only, validation 1 s"),
    Config("kuka-shorttest", "kuka", {"train": ("run1", 0, INF), "validate": ("run2", 0, INF),
                                      "test": ("run3", 5.0, 6.0)}, note="KUKA 1/2/3, test 1 s of run 3"),
    Config("kuka-mixedrate", "kuka", {"train": ("run1", 0, INF), "validate": ("run2", 0, INF),
                                      "test": ("run3", 0, INF)}, transform={"validate": subsample(5),
                                                                            "test": subsample(2)},
           note="KUKA 1/2/3: training at 200 Hz, validation at 40 Hz, test at 100 Hz"),
    Config("panda-mixedrate", "panda", {"train": ("log", 0, 13.84), "validate": ("log", 13.84, 17.2),
                                        "test": ("log", 17.2, INF)}, transform={"train": subsample(5),
                                                                                "test": subsample(10)},
           note="Panda 13.84 / 17.2 s: training at 200 Hz, validation at 1 kHz, test at 100 Hz"),
    Config("kuka-epoch", "kuka", {"train": ("run1", 0, INF), "validate": ("run2", 0, INF), "test": ("run3", 0, INF)},
           transform=epoch, note="KUKA 1/2/3, time stamps in seconds since 1970"),
    Config("kuka-shorttrain", "kuka", {"train": ("run1", 0, 5.0), "validate": ("run2", 0, INF),
                                       "test": ("run3", 0, INF)}, note="KUKA training: the first 5 s of run 1"),
    Config("kuka-sub10", "kuka", {"train": ("run1", 0, INF), "validate": ("run2", 0, INF), "test": ("run3", 0, INF)},
           transform=subsample(10), note="KUKA 1/2/3, every 10th sample (20 Hz)"),
    Config("panda-stamps", "panda", {"train": ("log", 0, 13.84), "validate": ("log", 13.84, 17.2),
                                     "test": ("log", 17.2, INF)}, transform=repeated_stamps,
           note="Panda 13.84 / 17.2 s, ten more time stamps repeated with new values"),
    Config("panda-split10", "panda", {"train": ("log", 0, 10.0), "validate": ("log", 10.0, 15.0),
                                      "test": ("log", 15.0, INF)}, note="Panda split at 10 s / 15 s"),
    Config("panda-swap", "panda", {"train": ("log", 6.84, INF), "validate": ("log", 3.5, 6.84),
                                   "test": ("log", 0, 3.5)}, note="Panda train > 6.84 s, validate 3.5-6.84, test < 3.5"),
    Config("panda-posonly", "panda", {"train": ("log", 0, 13.84), "validate": ("log", 13.84, 17.2),
                                      "test": ("log", 17.2, INF)}, transform=positions_only,
           note="Panda 13.84 / 17.2 s, positions only"),
    Config("panda-sub5", "panda", {"train": ("log", 0, 13.84), "validate": ("log", 13.84, 17.2),
                                   "test": ("log", 17.2, INF)}, transform=subsample(5),
           note="Panda 13.84 / 17.2 s, every 5th sample (about 200 Hz)"),
    Config("panda-shortval", "panda", {"train": ("log", 0, 13.84), "validate": ("log", 13.84, 15.0),
                                       "test": ("log", 17.2, INF)}, note="Panda, validation 1.16 s"),
    Config("panda-noval", "panda", {"train": ("log", 0, 13.84), "test": ("log", 17.2, INF)},
           note="Panda train < 13.84 s, no validation"),
    Config("tx40-sub2", "tx40", {"train": ("log", 0, 4.5), "validate": ("log", 4.5, 6.0), "test": ("log", 6.0, 7.6)},
           transform=subsample(2), note="TX40 4.5 / 6.0 s, every 2nd sample (2.5 kHz)"),
    Config("tx40-sub10", "tx40", {"train": ("log", 0, 4.5), "validate": ("log", 4.5, 6.0), "test": ("log", 6.0, 7.6)},
           transform=subsample(10), note="TX40 4.5 / 6.0 s, every 10th sample (500 Hz)"),
    Config("tx40-split", "tx40", {"train": ("log", 1.5, 6.0), "validate": ("log", 6.0, 7.6), "test": ("log", 0, 1.5)},
           transform=subsample(5), note="TX40 train 1.5-6 s, validate 6-7.6 s, test < 1.5 s; 1 kHz"),
    Config("tx40-stamps", "tx40", {"train": ("log", 0, 4.5), "validate": ("log", 4.5, 6.0), "test": ("log", 6.0, 7.6)},
           transform=lambda r: stamp_defects(subsample(5)(r)), note="TX40 at 1 kHz, 5 stamps repeated, 5 dropped"),
    Config("tx40-shortval", "tx40", {"train": ("log", 0, 4.5), "validate": ("log", 4.5, 5.5),
                                     "test": ("log", 6.0, 7.6)}, transform=subsample(5),
           note="TX40 at 1 kHz, validation 1 s"),
    Config("tx40-restval", "tx40", {"train": ("log", 0, 6.0), "validate": ("log", 7.6, 9.0),
                                    "test": ("log", 6.0, 7.6)}, transform=subsample(5),
           note="TX40 at 1 kHz, validation 7.6-9 s where the robot rests"),
    Config("tx40-resttrain", "tx40", {"train": ("log", 1.5, 9.0), "validate": ("log", 0, 1.5),
                                      "test": ("log", 6.0, 7.6)}, transform=subsample(5),
           note="TX40 at 1 kHz, training 1.5-9 s (its last 1.4 s at rest), validate < 1.5 s, test 6-7.6 s"),
    Config("tx40-resttest", "tx40", {"train": ("log", 0, 4.5), "validate": ("log", 4.5, 6.0),
                                     "test": ("log", 6.0, 9.0)}, transform=subsample(5),
           note="TX40 at 1 kHz, 4.5 / 6.0 s, the test record 6-9 s ends at rest"),
    Config("emps-sub20", "emps", {"train": ("estimation", 0, 16.56), "validate": ("estimation", 16.56, INF),
                                  "test": ("pulses", 0, INF)}, transform=subsample(20), note="EMPS at 50 Hz"),
    Config("emps-shortval", "emps", {"train": ("estimation", 0, 16.56), "validate": ("estimation", 16.56, 18.56),
                                     "test": ("pulses", 0, INF)}, note="EMPS, validation 2 s"),
    Config("emps-swap", "emps", {"train": ("estimation", 8.28, INF), "validate": ("estimation", 0, 8.28),
                                 "test": ("pulses", 0, INF)}, note="EMPS last two thirds / first third"),
    Config("emps-sub10", "emps", {"train": ("estimation", 0, 16.56), "validate": ("estimation", 16.56, INF),
                                  "test": ("pulses", 0, INF)}, transform=subsample(10), note="EMPS at 100 Hz"),
    Config("emps-stamps", "emps", {"train": ("estimation", 0, 16.56), "validate": ("estimation", 16.56, INF),
                                   "test": ("pulses", 0, INF)}, transform=stamp_defects,
           note="EMPS, 5 stamps repeated, 5 dropped"),
]


class SweepPlainFit(PlainFit):
    """:class:`bench_real_robots.PlainFit` whose cut-offs stay below 40 % of the slowest record's rate (the
    records of a configuration may be logged at different rates)."""

    def fit_on(self, train: Record, validate: Record, records: list[Record]) -> tuple[float, np.ndarray]:
        rate = min(1.0 / float(np.median(np.diff(np.unique(record.t)))) for record in records)
        return self.fit(train, validate, rate_hz=rate)


def _columns(prefix: str, values: np.ndarray) -> dict[str, np.ndarray]:
    return {f"{prefix}{j + 1}": values[:, j] for j in range(values.shape[1])}


def write(log: Log, record: Record, layout: str, path: Path) -> Path:
    if log.motor_side:
        matrix = tx40_transmission()
        # q_m = R q in the URDF's zeros, as bench_real_robots writes it (the plain fit uses the same q); the log's
        # own motor zeros (R q - TX40_ZERO * TX40_RATIOS) put joints 2 and 3 a quarter turn off the description's
        qm = record.q @ matrix.T
        taum = np.linalg.solve(matrix.T, record.tau.T).T
        columns = {"t": record.t, **_columns("qm", qm), **_columns("taum", taum)}
    else:
        columns = {"t": record.t, **_columns("q", record.q)}
        if record.dq is not None:
            columns |= _columns("dq", record.dq)
            if record.ddq is not None:
                columns |= _columns("ddq", record.ddq)
        columns |= _columns("tau", record.tau)
    frame = pd.DataFrame(columns)
    frame["t"] = [f"{value:.17g}" for value in record.t]  # every digit of the time stamps (an epoch clock's too)
    if layout == "shuffled":
        frame["temperature"] = 40.0 + 0.01 * np.arange(frame.shape[0])
        frame["status"] = 1
        frame = frame[list(reversed(frame.columns))]
    frame.to_csv(path, index=False, float_format="%.10g")
    return path


#: the verbs each configuration runs (``--verbs``)
VERBS = ("identify", "diagnose")


def run(arguments: list[str]) -> tuple[int, str]:
    process = subprocess.run([sys.executable, "-m", "oed", *arguments], capture_output=True, text=True)
    return process.returncode, process.stderr


def message(code: int, stderr: str) -> str:
    lines = [line for line in stderr.strip().splitlines() if line.strip()]
    flag = "TRACEBACK " if "Traceback (most recent call last)" in stderr else ""
    return f"exit {code}: {flag}{lines[-1][:160] if lines else ''}"


def config_records(config: Config, log: Log, folder: Path) -> tuple[dict[str, Record], dict[str, Path]]:
    """The configuration's records (sliced from ``log``, transformed) and the files written for them in ``folder``
    (``<name>_<role>.csv``), by role."""
    records, files = {}, {}
    for role, (name, start, stop) in config.roles.items():
        record = _slice(log.records[name], start, stop)
        transform = config.transform.get(role) if isinstance(config.transform, dict) else config.transform
        if transform is not None:
            record = transform(record)
        records[role] = record
        files[role] = write(log, record, config.layout, folder / f"{config.name}_{role}.csv")
    return records, files


def sweep(config: Config, folder: Path, logs: dict[str, Log], verbs: tuple[str, ...] = VERBS) -> dict:
    log = logs[config.robot]
    records, files = config_records(config, log, folder)
    validate = ["--validate", str(files["validate"])] if "validate" in files else []
    outcome = {"runs": {}, "messages": {}}
    for verb in verbs:
        result, predictions = folder / f"{config.name}_{verb}.json", folder / f"{config.name}_{verb}.csv"
        friction = ["--friction", FRICTION] if verb == "identify" else []
        started = time.perf_counter()
        code, stderr = run([verb, *log.robot, *log.options, "--data", str(files["train"]), *validate, *friction,
                            "--out", str(result), "--quiet"])
        seconds = time.perf_counter() - started
        if code != 0:
            outcome["messages"][verb] = message(code, stderr)
            outcome["runs"][verb] = None
            continue
        if "Traceback" in stderr:
            outcome["messages"][verb] = "exit 0 with a traceback on stderr"
        code, stderr = run(["predict", "--model", str(result), "--data", str(files["test"]), "--out",
                            str(predictions)])
        if code != 0:
            outcome["messages"][verb] = "predict " + message(code, stderr)
            outcome["runs"][verb] = None
            continue
        table = pd.read_csv(predictions)
        channels = [c for c in table.columns if c.startswith("tau") and c[3:].isdigit()]
        outcome["runs"][verb] = {"t": table["t"].to_numpy(), "predicted": table[channels].to_numpy(),
                                 "seconds": seconds, "result": json.loads(result.read_text())}
    test = records["test"]
    plain = SweepPlainFit(log.robot)
    cutoff, theta = plain.fit_on(records["train"], records.get("validate", records["train"]), list(records.values()))
    predicted, kept = plain.predict(test, cutoff, theta)
    common = np.flatnonzero(kept)
    at = {}
    for verb, value in outcome["runs"].items():
        if value is not None:
            at[verb] = at_recorded(test.t, value["t"], value["predicted"])
            common = np.intersect1d(common, at[verb][0])
    outcome["plain"] = np.mean((test.tau[common] - predicted[common]) ** 2, axis=0)
    outcome["cutoff"] = cutoff
    outcome["mse"] = {verb: None if common.size == 0 else np.mean((test.tau[common] - values[np.isin(index, common)]) ** 2, axis=0)
                      for verb, (index, values) in at.items()}
    outcome["samples"] = (common.shape[0], test.t.shape[0])
    outcome["at"] = at
    return outcome


def rows(config: Config, outcome: dict) -> list[str]:
    plain = outcome["plain"]
    lines = []
    for verb in outcome["runs"]:
        mse = outcome["mse"].get(verb)
        note = outcome["messages"].get(verb, "")
        if outcome["samples"][0] == 0 and verb in outcome["at"]:
            index = outcome["at"][verb][0]
            lines.append(f"| {config.name} | {verb} | – | – | – | exit 0, predicted {index.shape[0]} of "
                         f"{outcome['samples'][1]} test samples; the plain fit's filter keeps none |")
            continue
        if mse is None:
            lines.append(f"| {config.name} | {verb} | – | – | – | {note} |")
            continue
        ratio = mse / plain
        run = outcome["runs"][verb]
        chosen = (run["result"].get("model_selection") or {}).get("chosen", "")
        if verb == "diagnose":
            effects = [f"{e['spec']} on {','.join(e['channels'])}" for e in run["result"].get("effects", [])]
            chosen += "; effects: " + ("; ".join(effects) or "none")
        lines.append(f"| {config.name} | {verb} | {mse.sum() / plain.sum():.3f} | {ratio.mean():.3f} | "
                     + ", ".join(f"{r:.2f}" for r in ratio) + f" | exit 0 ({chosen}, {run['seconds']:.0f} s)"
                     + (f"; {note}" if note else "") + " |")
    return lines


HEADER = ["| configuration | verb | total / plain | mean joint / plain | per joint / plain | outcome |",
          "|---|---|---|---|---|---|"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", help="configurations, comma-separated (default: all)")
    parser.add_argument("--list", action="store_true", help="list the configurations and stop")
    parser.add_argument("--markdown", type=Path, help="append the table's rows to this file too")
    parser.add_argument("--verbs", default=",".join(VERBS), help="verbs to run, comma-separated (default: %(default)s)")
    args = parser.parse_args()
    configs = [c for c in CONFIGS if args.only is None or c.name in args.only.split(",")]
    if args.list:
        for config in CONFIGS:
            print(f"{config.name}: {config.note}")
        return
    if not DATA.is_dir():
        sys.exit(f"no real data at {DATA}")
    print("\n".join(HEADER), flush=True)
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        logs: dict[str, Log] = {}
        for config in configs:
            if config.robot not in logs:
                logs[config.robot] = {"kuka": kuka_log, "panda": panda_log, "emps": emps_log,
                                      "tx40": lambda: tx40_log(folder)}[config.robot]()
            outcome = sweep(config, folder, logs, tuple(args.verbs.split(",")))
            block = rows(config, outcome)
            block[-1] += f" <!-- plain cut-off {outcome['cutoff']:g} Hz; {outcome['samples'][0]} of " \
                         f"{outcome['samples'][1]} test samples -->"
            print("\n".join(block), flush=True)
            if args.markdown is not None:
                with args.markdown.open("a") as handle:
                    handle.write("\n".join(block) + "\n")


if __name__ == "__main__":
    main()
