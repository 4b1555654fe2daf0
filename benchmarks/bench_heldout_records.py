"""The default ``oed identify`` on four real robots, judged on a record no choice saw.

For each robot of ``../shared/data`` with torques (KUKA LWR4+, Franka Panda, EMPS, Stäubli TX40) the logs are
written as CSV files (training, validation, test: disjoint records or disjoint windows of one log, below), then
``oed identify --friction viscous,coulomb,offset --data TRAIN --validate VALIDATE`` runs with every other option
at its default, and ``oed predict`` measures the error on the test record against the torques as recorded. Prints
one table row per robot: per-joint test MSE, their sum, the preprocessing chosen and the seconds taken.

The splits (none tuned to any result):

* KUKA LWR4+: runs 1, 2, 3 (train, validate, test); measured ``dq, ddq``.
* Franka Panda (Gaz et al.): the logger's record as written (jittered stamps, repeated rows, stalls), with the
  logged velocity: train t < 13.84 s (the ramp and the first period), validate 13.84–17.4 s, test the rest.
* EMPS: train the first 16 s of ``DATA_EMPS``, validate its rest, test ``DATA_EMPS_PULSES`` (force ``gtau·vir``).
* Stäubli TX40: motor side converted to the joints (reductions ``[32, 32, 45, -48, 45, 32]``, the wrist's motor 6
  turning with joints 5 and 6, joint torques ``Jᵀ τ_m``; joints 2 and 3 zeros moved by ∓π/2): train t < 5.25 s,
  validate 5.25–6.4 s, test 6.4–7.6 s (the robot rests after).

Run: ``.venv/bin/python benchmarks/bench_heldout_records.py [--robots kuka,panda,emps,tx40] [--work DIR]``
(``PYTHONPATH=<a checkout>`` runs another version of the toolkit on the same files).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
FRICTION = "viscous,coulomb,offset"


def frame(t, q, tau, dq=None) -> pd.DataFrame:
    columns = {"t": t}
    columns.update({f"q{j + 1}": q[:, j] for j in range(q.shape[1])})
    if dq is not None:
        columns.update({f"dq{j + 1}": dq[:, j] for j in range(q.shape[1])})
    columns.update({f"tau{j + 1}": tau[:, j] for j in range(q.shape[1])})
    return pd.DataFrame(columns)


def windows(table: pd.DataFrame, edges: list[float]) -> list[pd.DataFrame]:
    return [table[(table.t >= low) & (table.t < high)] for low, high in zip(edges[:-1], edges[1:])]


def kuka(folder: Path) -> tuple[list[str], list[pd.DataFrame]]:
    from estimation.datasets.kuka import load_kuka_run

    runs = [load_kuka_run(DATA / "kuka_lwr4" / f"kuka_lwr4_HW_measurements_{k}.npz") for k in (1, 2, 3)]
    tables = [frame(run.t, run.q, run.tau, run.dq).assign(**{f"ddq{j + 1}": run.ddq[:, j] for j in range(7)})
              for run in runs]
    return ["--urdf", str(DATA / "kuka_lwr4" / "kuka_lwr4.urdf")], tables


def panda(folder: Path) -> tuple[list[str], list[pd.DataFrame]]:
    log = DATA / "panda" / "Trajectory_1" / "rbt_log"
    read = lambda name: np.loadtxt(log / f"exciting_traj_{name}.txt").reshape(-1)  # noqa: E731
    t = read("time")
    t = t - t[0]
    q, dq, tau = (read(name).reshape(-1, 7) for name in ("positions", "velocity", "torques"))
    return ["--urdf", str(DATA / "panda" / "panda_gaz.urdf")], windows(frame(t, q, tau, dq), [0.0, 13.84, 17.4, 1e9])


def emps(folder: Path) -> tuple[list[str], list[pd.DataFrame]]:
    from estimation.datasets.shared import load_emps

    tables = []
    for which in ("estimation", "validation"):
        data = load_emps(DATA / "emps", which)
        tables.append(frame(data.t - data.t[0], data.qm[:, None], data.force[:, None]))
    train, validate = windows(tables[0], [0.0, 16.0, 1e9])
    return ["--robot", "emps"], [train, validate, tables[1]]


def tx40(folder: Path) -> tuple[list[str], list[pd.DataFrame]]:
    ratios = np.array([32.0, 32.0, 45.0, -48.0, 45.0, 32.0])
    motor = pd.read_csv(DATA / "tx40" / "pos_read_data.csv").to_numpy(dtype=float)
    torque_m = pd.read_csv(DATA / "tx40" / "curr_data.csv").to_numpy(dtype=float)
    coupling = np.diag(ratios)
    coupling[5, 4] = ratios[5]  # motor 6 turns with joints 5 and 6
    q = np.linalg.solve(coupling, motor.T).T
    q[:, 1] -= np.pi / 2
    q[:, 2] += np.pi / 2
    tau = torque_m @ coupling  # τ = Jᵀ τ_m
    t = 0.0002 * np.arange(q.shape[0])
    return (["--urdf", str(DATA / "tx40" / "tx40_mdh_modified.urdf")],
            windows(frame(t, q, tau), [0.0, 5.25, 6.4, 7.6]))


ROBOTS = {"kuka": kuka, "panda": panda, "emps": emps, "tx40": tx40}


def run(name: str, work: Path) -> dict:
    from oed.cli import main

    folder = work / name
    folder.mkdir(parents=True, exist_ok=True)
    robot, tables = ROBOTS[name](folder)
    paths = []
    for role, table in zip(("train", "validate", "test"), tables):
        path = folder / f"{role}.csv"
        table.to_csv(path, index=False, float_format="%.10g")
        paths.append(path)
    result, metrics = folder / "result.json", folder / "metrics.json"
    started = time.perf_counter()
    output = io.StringIO()
    with contextlib.redirect_stdout(output), contextlib.redirect_stderr(output):
        code = main(["identify", *robot, "--friction", FRICTION, "--data", str(paths[0]), "--validate", str(paths[1]),
                     "--out", str(result)])
        if code == 0:
            code = main(["predict", "--model", str(result), "--data", str(paths[2]), "--metrics", str(metrics),
                         "--out", str(folder / "predicted.csv")])
    seconds = time.perf_counter() - started
    if code != 0:
        return {"robot": name, "exit": code, "seconds": seconds, "output": output.getvalue()[-2000:]}
    document = json.loads(result.read_text())
    mse = json.loads(metrics.read_text())["mse"]
    plan = document.get("preprocessing") or {}
    return {"robot": name, "exit": 0, "seconds": seconds, "mse": mse, "total": float(sum(mse.values())),
            "preprocessing": {key: plan.get(key) for key in ("method", "cutoff_hz", "frequency_hz", "harmonics",
                                                              "trimmed_s")}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default=",".join(ROBOTS))
    parser.add_argument("--work", type=Path, default=None, help="folder for the files (default: a temporary one)")
    parser.add_argument("--json", type=Path, default=None, help="write the rows as JSON")
    args = parser.parse_args()
    if not DATA.is_dir():
        raise SystemExit(f"{DATA} is absent: the real logs are needed")
    with tempfile.TemporaryDirectory() as scratch:
        work = args.work or Path(scratch)
        rows = [run(name, work) for name in args.robots.split(",")]
    for row in rows:
        if row["exit"]:
            print(f"{row['robot']}: exit {row['exit']} ({row['seconds']:.0f} s)\n{row['output']}")
            continue
        joints = " / ".join(f"{value:.4g}" for value in row["mse"].values())
        print(f"{row['robot']}: test MSE {joints}; total {row['total']:.4g} ({row['seconds']:.0f} s) "
              f"{row['preprocessing']}")
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
