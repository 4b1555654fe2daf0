"""Benchmark (issue 34): the default ``oed identify`` against a plain least-squares fit and the consistent fit, per
joint, on a record no choice saw, on the real robots of ``../shared/data``.

Each robot gives three records: training, validation (another motion where the data allow it) and test. Compared
on the test record, per joint, MSE against the torques as recorded, every model on the same samples (those
``oed predict`` predicted, but rows that repeat the previous row on every channel: a logger's re-sent packets,
which the toolkit drops when it reads a record, :func:`resent`):

``default``
    ``oed identify --data TRAIN --validate VALIDATE --friction viscous,coulomb,offset`` (no other option: the
    derivatives, the weighting and the model among OLS, WLS and the consistent fit chosen by the toolkit), then
    ``oed predict --data TEST``;
``consistent``
    the same with ``--consistent`` (the prior weight chosen on the validation record);
``toolkit OLS``
    the same with ``--method ols``;
``diagnose``
    ``oed diagnose --data TRAIN --validate VALIDATE`` (its own defaults: the declared viscous model, the effects
    found and confirmed on the validation record, then the default answer between the adopted model and its
    consistent refit, ``model_selection``), then ``oed predict --data TEST``;
``plain OLS``
    what a user writes without the toolkit: Pinocchio's joint-torque regressor plus viscous, Coulomb and offset
    columns per joint, reduced to numerically independent columns (:meth:`PlainFit.base_columns`), ordinary least
    squares, the logged velocity (else the positions'
    derivative) and the torques low-passed by a zero-phase 4th-order Butterworth filter, the motion
    differentiated (:func:`filtered_motion`), ``2 / cut-off`` seconds trimmed at each edge, the cut-off chosen
    among :data:`CUTOFFS_HZ` by the total validation MSE against the recorded torques.

Robots (the records' facts are in ``../shared/data/README.md``):

``kuka``
    KUKA LWR4+, runs 1 / 2 / 3 (run 2 repeats run 1's motion; run 3 is twice as fast); the logged ``dq``, ``ddq``
    given to the toolkit, as a user would.
``panda``
    Franka Panda, one 20.5 s log split at 13.84 s (the ramp and the first period: training) and 17.2 s
    (validation, then test); positions, logged velocities and torques given as logged (jitter, repeated rows).
``tx40``
    Stäubli TX40, motor-side positions and torques at 5 kHz with the coupled wrist (``q_m6 = N6 (q5 + q6)``) given
    by a transmission file; joints 2 and 3 moved to the URDF's zeros; split at 4.5 s and 6.0 s of the 7.6 s of
    motion.
``emps``
    EMPS (one prismatic axis): ``DATA_EMPS`` split at two thirds (training, validation), tested on
    ``DATA_EMPS_PULSES`` (which holds external force pulses no model has).

Run: ``python benchmarks/bench_real_robots.py [--robots kuka,panda,tx40,emps] [--runs default,diagnose,...]
[--markdown table.md]``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pinocchio as pin
from scipy.linalg import qr
from scipy.signal import butter, sosfiltfilt

from dynamics.pinocchio_bridge import to_pinocchio
from dynamics.robots import load_robot
from estimation.datasets.kuka import load_kuka_run
from estimation.datasets.shared import load_emps
from oed.cli import main

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
FRICTION = "viscous,coulomb,offset"
#: the plain fit's cut-off candidates (those below 40 % of the sampling rate)
CUTOFFS_HZ = (1.0, 2.0, 3.0, 5.0, 8.0, 12.0, 20.0, 30.0, 50.0, 80.0, 120.0, 200.0)
#: the plain fit trims this many periods of its cut-off at each edge of a record (where the filtered acceleration
#: settles; the toolkit's own trim is about 1.8)
SETTLING = 2.0
TX40_RATIOS = np.array([32.0, 32.0, 45.0, -48.0, 45.0, 32.0])
TX40_ZERO = np.array([0.0, -np.pi / 2, np.pi / 2, 0.0, 0.0, 0.0])  # q_urdf = q_log + TX40_ZERO


@dataclass
class Record:
    """Joint-side time, positions and torques as recorded (the plain fit's input and everyone's truth)."""

    t: np.ndarray
    q: np.ndarray
    tau: np.ndarray
    dq: np.ndarray | None = None  # the logged velocity, when the log has one


@dataclass
class Case:
    name: str
    robot: list[str]  # --urdf FILE, --mjcf FILE (and --joint-names A,B,C) or --robot NAME
    records: dict[str, Record]  # train, validate, test
    files: dict[str, Path] = field(default_factory=dict)  # what the toolkit reads
    options: list[str] = field(default_factory=list)


def _write(frame: pd.DataFrame, path: Path) -> Path:
    frame.to_csv(path, index=False, float_format="%.10g")
    return path


def _columns(prefix: str, values: np.ndarray) -> dict[str, np.ndarray]:
    return {f"{prefix}{j + 1}": values[:, j] for j in range(values.shape[1])}


def kuka(folder: Path) -> Case:
    source = DATA / "kuka_lwr4"
    case = Case("KUKA LWR4+ (runs 1 / 2 / 3)", ["--urdf", str(source / "kuka_lwr4.urdf")], {})
    for role, index in (("train", 1), ("validate", 2), ("test", 3)):
        run = load_kuka_run(source / f"kuka_lwr4_HW_measurements_{index}.npz")
        case.records[role] = Record(run.t, run.q, run.tau, run.dq)
        frame = pd.DataFrame({"t": run.t, **_columns("q", run.q), **_columns("dq", run.dq), **_columns("ddq", run.ddq),
                              **_columns("tau", run.tau)})
        case.files[role] = _write(frame, folder / f"kuka_{role}.csv")
    return case


def panda(folder: Path) -> Case:
    source = DATA / "panda"
    log = source / "Trajectory_1" / "rbt_log"
    t = np.loadtxt(log / "exciting_traj_time.txt").reshape(-1)
    q, dq, tau = (np.loadtxt(log / f"exciting_traj_{name}.txt").reshape(-1, 7) for name in ("positions", "velocity",
                                                                                               "torques"))
    case = Case("Franka Panda (one log: t < 13.84 s / 13.84-17.2 s / > 17.2 s)", ["--urdf", str(source / "panda_gaz.urdf")],
                {})
    for role, (start, stop) in (("train", (0.0, 13.84)), ("validate", (13.84, 17.2)), ("test", (17.2, np.inf))):
        keep = (t >= start) & (t < stop)
        case.records[role] = Record(t[keep], q[keep], tau[keep], dq[keep])
        frame = pd.DataFrame({"t": t[keep], **_columns("q", q[keep]), **_columns("dq", dq[keep]),
                              **_columns("tau", tau[keep])})
        case.files[role] = _write(frame, folder / f"panda_{role}.csv")
    return case


def tx40_transmission() -> np.ndarray:
    """``R`` with ``q_m = R q``: the gear ratios, motor 6 turning with ``q5 + q6``."""
    matrix = np.diag(TX40_RATIOS)
    matrix[5, 4] = TX40_RATIOS[5]
    return matrix


def tx40(folder: Path) -> Case:
    source = DATA / "tx40"
    qm = pd.read_csv(source / "pos_read_data.csv").to_numpy(dtype=float)
    taum = pd.read_csv(source / "curr_data.csv").to_numpy(dtype=float)
    t = np.arange(qm.shape[0]) * 0.0002
    matrix = tx40_transmission()
    qm = qm + TX40_ZERO * TX40_RATIOS  # the URDF's zeros (joints 2 and 3), on the motor side
    q = np.linalg.solve(matrix, qm.T).T
    tau = taum @ matrix  # τ = Rᵀ τ_m
    transmission = folder / "tx40_transmission.json"
    transmission.write_text(json.dumps({"ratios": TX40_RATIOS.tolist(), "couplings": {"6": {"5": TX40_RATIOS[5]}}}))
    case = Case("Stäubli TX40 (motor side, coupled wrist; 0-4.5 s / 4.5-6.0 s / 6.0-7.6 s)",
                ["--urdf", str(source / "tx40_mdh_modified.urdf")], {}, options=["--transmission", str(transmission)])
    for role, (start, stop) in (("train", (0.0, 4.5)), ("validate", (4.5, 6.0)), ("test", (6.0, 7.6))):
        keep = (t >= start) & (t < stop)
        case.records[role] = Record(t[keep], q[keep], tau[keep])
        frame = pd.DataFrame({"t": t[keep], **_columns("qm", qm[keep]), **_columns("taum", taum[keep])})
        case.files[role] = _write(frame, folder / f"tx40_{role}.csv")
    return case


def emps(folder: Path) -> Case:
    source = DATA / "emps"
    estimation, pulses = load_emps(source, "estimation"), load_emps(source, "validation")
    split = 2 * estimation.t.shape[0] // 3
    parts = {"train": (estimation, slice(0, split)), "validate": (estimation, slice(split, None)),
             "test": (pulses, slice(None))}
    case = Case("EMPS (DATA_EMPS: first two thirds / last third; test DATA_EMPS_PULSES)", ["--robot", "emps"], {})
    for role, (data, part) in parts.items():
        t, q, force = data.t[part], data.qm[part, None], data.force[part, None]
        case.records[role] = Record(t, q, force)
        case.files[role] = _write(pd.DataFrame({"t": t, "q1": q[:, 0], "tau1": force[:, 0]}), folder / f"emps_{role}.csv")
    return case


ROBOTS = {"kuka": kuka, "panda": panda, "tx40": tx40, "emps": emps}


def _filtered(t_record: np.ndarray, fresh: np.ndarray, values: np.ndarray, cutoff_hz: float
              ) -> tuple[np.ndarray, np.ndarray, float]:
    """``(grid, filtered, step)``: ``values`` at the ``fresh`` rows, on a uniform grid at their median step,
    low-passed by a zero-phase 4th-order Butterworth filter (second-order sections)."""
    t, values = t_record[fresh], values[fresh]
    step = float(np.median(np.diff(t)))
    grid = np.arange(t[0], t[-1] + 0.5 * step, step)
    uniform = np.column_stack([np.interp(grid, t, column) for column in values.T])
    return grid, sosfiltfilt(butter(4, cutoff_hz / (0.5 / step), output="sos"), uniform, axis=0), step


def _back(t_record: np.ndarray, grid: np.ndarray, series: np.ndarray) -> np.ndarray:
    return np.column_stack([np.interp(t_record, grid, column) for column in series.T])


def filtered_motion(record: Record, cutoff_hz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``q, dq, ddq, tau`` filtered at the recorded samples: the rows that repeat the previous one (a logger's
    re-sent packets) left out, the rest on a uniform grid at the median rate, low-passed by a zero-phase 4th-order
    Butterworth filter: the positions (differentiated twice), or the logged velocity if the log has one
    (differentiated once), and the torques alike (the fit's targets; errors are always against the recorded
    torques); interpolated back to the recorded time stamps."""
    fresh = np.r_[True, np.any(np.diff(record.q, axis=0) != 0, axis=1)]
    grid, q, step = _filtered(record.t, fresh, record.q, cutoff_hz)
    if record.dq is None:
        dq = np.gradient(q, step, axis=0)
    else:
        dq = _filtered(record.t, fresh, record.dq, cutoff_hz)[1]
    ddq = np.gradient(dq, step, axis=0)
    tau = _filtered(record.t, fresh, record.tau, cutoff_hz)[1]
    return tuple(_back(record.t, grid, series) for series in (q, dq, ddq, tau))


class PlainFit:
    """The plain least-squares fit (module docstring) of one robot."""

    def __init__(self, robot_arguments: list[str]) -> None:
        options = dict(zip(robot_arguments[::2], robot_arguments[1::2]))
        path, names = options.get("--urdf", options.get("--mjcf")), options.get("--joint-names")
        robot = (load_robot(urdf=path, joint_names=None if names is None else names.split(",")) if path is not None
                 else load_robot(options["--robot"]))
        self.model = to_pinocchio(robot)
        self.data = self.model.createData()
        self.n = robot.n_joints
        self.columns = self.base_columns()

    def base_columns(self, samples: int = 300, tolerance: float = 1e-8) -> np.ndarray:
        """The independent columns (numerical base parameters): a column-pivoted QR of the regressor of random
        states, the columns whose pivot exceeds ``tolerance`` times the largest (Gautier's numerical method)."""
        generator = np.random.default_rng(0)
        states = [generator.uniform(-np.pi, np.pi, (samples, self.n)) for _ in range(3)]
        Y = self.stacked(*states).reshape(-1, 13 * self.n)
        _, R, pivot = qr(Y, mode="economic", pivoting=True)
        rank = int(np.sum(np.abs(np.diag(R)) > tolerance * abs(R[0, 0])))
        return np.sort(pivot[:rank])

    def regressor(self, record: Record, cutoff_hz: float) -> np.ndarray:
        """``(N, n, 10 n + 3 n)``: rigid body, viscous, Coulomb, offset, the derivatives filtered at ``cutoff_hz``
        (:func:`filtered_motion`) at the recorded samples."""
        q, dq, ddq, _ = filtered_motion(record, cutoff_hz)
        return self.stacked(q, dq, ddq)[:, :, self.columns]

    def stacked(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
        """``(N, n, 13 n)``: every column along ``q, dq, ddq``."""
        n = self.n
        Y = np.zeros((q.shape[0], n, 13 * n))
        for k in range(q.shape[0]):
            Y[k, :, : 10 * n] = pin.computeJointTorqueRegressor(self.model, self.data, q[k], dq[k], ddq[k])
        rows = np.arange(n)
        Y[:, rows, 10 * n + rows] = dq
        Y[:, rows, 11 * n + rows] = np.sign(dq)
        Y[:, rows, 12 * n + rows] = 1.0
        return Y

    @staticmethod
    def kept(record: Record, cutoff_hz: float) -> np.ndarray:
        """The samples beyond the filter's settling at each edge, :data:`SETTLING` periods of the cut-off."""
        trim = SETTLING / cutoff_hz
        return (record.t >= record.t[0] + trim) & (record.t <= record.t[-1] - trim)

    def fit(self, train: Record, validate: Record, *, rate_hz: float | None = None) -> tuple[float, np.ndarray]:
        """The cut-off of the smallest total validation MSE and its parameters. Each cut-off is fitted on the
        training samples its filter keeps and scored on the same validation samples (those the lowest cut-off
        keeps); cut-offs whose settling would take more than a tenth of the validation record are not tried, nor
        those above 40 % of ``rate_hz`` (default the training record's rate, its fresh rows)."""
        fresh = np.r_[True, np.any(np.diff(train.q, axis=0) != 0, axis=1)]
        rate = 1.0 / float(np.median(np.diff(train.t[fresh]))) if rate_hz is None else rate_hz
        duration = validate.t[-1] - validate.t[0]
        cutoffs = [c for c in CUTOFFS_HZ if c < 0.4 * rate and SETTLING / c <= 0.1 * duration]
        scored = self.kept(validate, min(cutoffs))
        best = None
        for cutoff in cutoffs:
            keep = self.kept(train, cutoff)
            Y = self.regressor(train, cutoff)[keep]
            target = filtered_motion(train, cutoff)[3][keep]
            theta = np.linalg.lstsq(Y.reshape(-1, Y.shape[2]), target.reshape(-1), rcond=None)[0]
            residual = validate.tau[scored] - (self.regressor(validate, cutoff) @ theta)[scored]
            error = float(np.mean(residual**2, axis=0).sum())
            if best is None or error < best[0]:
                best = (error, cutoff, theta)
        return best[1], best[2]

    def predict(self, record: Record, cutoff_hz: float, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The prediction along ``record`` and the samples it holds (:meth:`kept`)."""
        return self.regressor(record, cutoff_hz) @ theta, self.kept(record, cutoff_hz)


def run_quiet(arguments: list[str]) -> tuple[int, str]:
    """``oed ARGUMENTS`` in this process with its output held: ``(exit code, stdout)``; a failure's last lines of
    stderr printed."""
    with contextlib.redirect_stdout(io.StringIO()) as out, contextlib.redirect_stderr(io.StringIO()) as err:
        code = main(arguments)
    if code != 0:
        print(f"  exit {code}: oed {' '.join(arguments[:1])}: {err.getvalue().strip()[-600:]}", file=sys.stderr)
    return code, out.getvalue()


def toolkit(case: Case, folder: Path, label: str, options: list[str], verb: str = "identify") -> dict | None:
    """Identify (``verb="identify"``, the model class :data:`FRICTION`) or diagnose (``verb="diagnose"``, its own
    defaults) with ``options``, predict the test record: ``{t, predicted, result}`` or ``None`` on failure."""
    result, predictions = folder / f"{label}.json", folder / f"{label}.csv"
    started = time.perf_counter()
    friction = ["--friction", FRICTION] if verb == "identify" else []
    code, _ = run_quiet([verb, *case.robot, *case.options, "--data", str(case.files["train"]), "--validate",
                      str(case.files["validate"]), *friction, *options, "--out", str(result)])
    seconds = time.perf_counter() - started
    if code != 0:
        return None
    code, _ = run_quiet(["predict", "--model", str(result), "--data", str(case.files["test"]), "--out", str(predictions)])
    if code != 0:
        return None
    table = pd.read_csv(predictions)
    channels = [column for column in table.columns if column.startswith("tau") and column[3:].isdigit()]
    document = json.loads(result.read_text())
    drift = document.get("friction_drift")
    if drift:  # the friction drift check (h-drift): each joint's scale on the validation record, marked ones starred
        print(f"  {label}: friction scale on the validation record: " + ", ".join(
            f"{name} {entry['scale']:.3f} ± {entry['std']:.2g}{' *' if entry['marked'] else ''}"
            for name, entry in drift["joints"].items()), flush=True)
    halves = document.get("training_stationarity")
    if halves:  # the torque gains fitted on each half of the training record (h-payload20)
        print(f"  {label}: torque gains on the training record's halves: " + ", ".join(
            f"{name} {entry['first_half']:.4g} / {entry['second_half']:.4g} (t {entry['t']:.2g}, limit "
            f"{entry['t_limit']:.2g}){' *' if entry['disagree'] else ''}" for name, entry in halves["channels"].items())
            + f"; the answer fitted on its {halves['answer_fitted_on']}" * (halves["answer_fitted_on"] != "whole"),
            flush=True)
    return {"t": table["t"].to_numpy(), "predicted": table[channels].to_numpy(), "result": document,
            "seconds": seconds}


def at_recorded(t_record: np.ndarray, t_predicted: np.ndarray, predicted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(indices, values)``: the prediction at the recorded time stamps it covers (linear in time between its
    own samples: the states interpolated, never the recorded torques; none within a gap of its samples)."""
    step = float(np.median(np.diff(t_predicted)))
    inside = (t_record >= t_predicted[0]) & (t_record <= t_predicted[-1])
    nearest = np.abs(t_predicted[np.clip(np.searchsorted(t_predicted, t_record), 0, t_predicted.shape[0] - 1)]
                     - t_record)
    previous = np.abs(t_predicted[np.clip(np.searchsorted(t_predicted, t_record) - 1, 0, t_predicted.shape[0] - 1)]
                      - t_record)
    index = np.flatnonzero(inside & (np.minimum(nearest, previous) <= 1.5 * step))
    values = np.column_stack([np.interp(t_record[index], t_predicted, column) for column in predicted.T])
    return index, values


def resent(record: Record) -> np.ndarray:
    """The rows that repeat the previous row on every channel (``q``, a logged ``dq``, ``tau``): a logger re-sending
    its last packet at a later time stamp, not a sample of the motion at that stamp. The toolkit drops them when it
    reads a record, the plain fit leaves them out of its filter; no model is scored on them."""
    data = np.column_stack([record.q, record.tau] + ([] if record.dq is None else [record.dq]))
    return np.r_[False, np.all(np.diff(data, axis=0) == 0, axis=1)]


#: the toolkit's runs compared: label, file stem, options[, verb]
RUNS = (("default", "default", ()), ("consistent", "consistent", ("--consistent",)),
        ("toolkit OLS", "ols", ("--method", "ols")), ("diagnose", "diagnose", (), "diagnose"))


def compare(case: Case, folder: Path, labels: tuple[str, ...] = tuple(run[0] for run in RUNS)) -> dict:
    """Per joint test MSE of the toolkit's runs ``labels`` and the plain fit at the recorded samples every toolkit
    run predicted (the re-sent rows left out: :func:`resent`)."""
    runs = {run[0]: toolkit(case, folder, run[1], list(run[2]), *run[3:]) for run in RUNS if run[0] in labels}
    test = case.records["test"]
    at = {label: None if run is None else at_recorded(test.t, run["t"], run["predicted"]) for label, run in runs.items()}
    common = None
    for value in at.values():
        if value is not None:
            common = set(value[0].tolist()) if common is None else common & set(value[0].tolist())
    common = np.array(sorted(common))
    plain = PlainFit(case.robot)
    cutoff, theta = plain.fit(case.records["train"], case.records["validate"])
    predicted, kept = plain.predict(test, cutoff, theta)
    common = common[kept[common] & ~resent(test)[common]]
    mse = {label: None if value is None else
           np.mean((test.tau[value[0][np.isin(value[0], common)]] - value[1][np.isin(value[0], common)]) ** 2, axis=0)
           for label, value in at.items()}
    mse["plain OLS"] = np.mean((test.tau[common] - predicted[common]) ** 2, axis=0)
    default = runs["default"]["result"] if runs.get("default") is not None else None
    diagnosed = runs["diagnose"]["result"] if runs.get("diagnose") is not None else None
    return {"mse": mse, "cutoff": cutoff, "samples": common.shape[0], "of": test.t.shape[0],
            "selection": None if default is None else default.get("model_selection"),
            "diagnose_selection": None if diagnosed is None else diagnosed.get("model_selection"),
            "effects": None if diagnosed is None else [f"{e['spec']} on {','.join(e['channels'])}"
                                                        for e in diagnosed.get("effects", [])],
            "preprocessing": None if default is None else default.get("preprocessing"),
            "seconds": {label: None if run is None else run["seconds"] for label, run in runs.items()}}


def table(name: str, outcome: dict) -> list[str]:
    mse = outcome["mse"]
    plain = mse["plain OLS"]
    n = plain.shape[0]
    lines = [f"**{name}**: test MSE per joint (N²m², N² for EMPS) on {outcome['samples']} of {outcome['of']} test "
             f"samples; plain OLS cut-off {outcome['cutoff']:g} Hz (chosen on the validation record)", "",
             "| model | " + " | ".join(f"j{j + 1}" for j in range(n))
             + " | total | total / plain | mean joint / plain | worst joint / plain |",
             "|---|" + "---|" * (n + 4)]
    for label, values in mse.items():
        if values is None:
            lines.append(f"| {label} | " + " | ".join("–" for _ in range(n)) + " | failed | – | – | – |")
            continue
        ratio = values / plain
        lines.append(f"| {label} | " + " | ".join(f"{v:.4g}" for v in values)
                     + f" | {values.sum():.4g} | {values.sum() / plain.sum():.3f} | {ratio.mean():.3f} "
                     f"| {ratio.max():.3f} (j{ratio.argmax() + 1}) |")
    selection = outcome["selection"]
    if selection is not None:
        scores = ", ".join(f"{c['name']} {c['score']:.4g}" for c in selection["candidates"] if c["score"] is not None)
        lines += ["", f"default chose **{selection['chosen']}** ({selection['selection']}; validation scores: "
                      f"{scores or 'none'}{paired_text(selection)}); derivatives: "
                      f"{derivatives(outcome['preprocessing'])}"]
    selection = outcome.get("diagnose_selection")
    if selection is not None:
        scores = ", ".join(f"{c['name']} {c['score']:.4g}" if c["score"] is not None else f"{c['name']} (none)"
                           for c in selection["candidates"])
        lines += ["", f"diagnose chose **{selection['chosen']}** ({selection['selection']}; validation scores: "
                      f"{scores}{paired_text(selection)}); effects adopted: {', '.join(outcome['effects']) or 'none'}"]
    return lines


def paired_text(selection: dict) -> str:
    """The paired differences of the consistent candidate's validation score to the best's and of ordinary least
    squares' to the weighted fit's, each ± its standard error, when compared (``model_selection.paired_difference``,
    ``model_selection.weighting_difference``), and whether each is within the sampling error."""
    text = ""
    for paired in (selection.get("paired_difference"), selection.get("weighting_difference")):
        if paired:
            text += (f"; {paired['regularised']} − {paired['best']} {paired['difference']:.3g} ± "
                     f"{paired['standard_error']:.2g}"
                     + (", within the sampling error" if paired["within_noise"] else ", beyond the sampling error"))
    return text


def derivatives(plan: dict) -> str:
    """The default's derivatives in a few words: the method, and how it was chosen (on the training record's
    held-out blocks, or on the validation record, then with the training record's own choice)."""
    text = plan.get("method", "?")
    if plan.get("method") == "butterworth":
        text += f" {plan['cutoff_hz']:.4g} Hz" + (" (dq from the positions)" if plan.get("velocity_from_positions")
                                                  else "")
    elif plan.get("method") == "fourier":
        text += f" {plan['frequency_hz']:.4g} Hz, {plan['harmonics']} harmonics"
    if plan.get("selection"):
        text += f", chosen by {plan['selection']}"
    if plan.get("held_out_choice"):
        text += f" (the training record's blocked cross-validation: {plan['held_out_choice']})"
    return text


def main_benchmark() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="kuka,panda,tx40,emps")
    parser.add_argument("--markdown", type=Path, help="write the tables to this file too")
    parser.add_argument("--runs", default=",".join(run[0] for run in RUNS),
                        help="the toolkit's runs, comma-separated (default: all)")
    args = parser.parse_args()
    if not DATA.is_dir():
        sys.exit(f"no real data at {DATA}")
    lines = []
    with tempfile.TemporaryDirectory() as folder:
        for key in args.robots.split(","):
            started = time.perf_counter()
            case = ROBOTS[key](Path(folder))
            outcome = compare(case, Path(folder), tuple(args.runs.split(",")))
            block = table(case.name, outcome)
            print("\n".join(block) + f"\n({time.perf_counter() - started:.0f} s; identify: "
                  + ", ".join(f"{label} {s:.1f} s" for label, s in outcome["seconds"].items() if s is not None) + ")\n",
                  flush=True)
            lines += block + [""]
    if args.markdown is not None:
        args.markdown.write_text("\n".join(lines))


if __name__ == "__main__":
    main_benchmark()
