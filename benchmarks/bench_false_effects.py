"""No false effects on real data: what the diagnosis names and how its model predicts a record no choice saw.

* KUKA LWR4+ (``../shared/data/kuka_lwr4``): ``oed diagnose`` trained on run 1, validated on run 2 (a repeat of run
  1's motion), then ``oed predict`` on run 3 (a twice faster trajectory): run 3's MSE per joint, the effects named,
  and the wall time of the diagnosis.
* EMPS (``../shared/data/emps``): ``diagnose`` from mass + viscous friction on the estimation record, confirmed on the
  validation record: the effects named and the validation MSE against the force as recorded.

``PYTHONPATH=. python benchmarks/bench_false_effects.py [JOBS [OPTION …]]`` (JOBS default 1; options go to
``oed diagnose`` on the KUKA, e.g. ``1 --unseen-stretches``; one BLAS thread: ``OMP_NUM_THREADS=1``).
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"


def _parquet(run, path: Path) -> str:
    table = {"t": run.t}
    for name, values in (("q", run.q), ("dq", run.dq), ("ddq", run.ddq), ("tau", run.tau)):
        table.update({f"{name}{j + 1}": values[:, j] for j in range(values.shape[1])})
    pd.DataFrame(table).to_parquet(path)
    return str(path)


def kuka(folder: Path, jobs: str, *options: str) -> None:
    from estimation.datasets.kuka import load_kuka_run
    from oed.cli import main

    runs = [load_kuka_run(folder / f"kuka_lwr4_HW_measurements_{index}.npz") for index in (1, 2, 3)]
    with tempfile.TemporaryDirectory() as directory:
        tmp = Path(directory)
        paths = [_parquet(run, tmp / f"run{index}.parquet") for index, run in enumerate(runs, start=1)]
        report, metrics = tmp / "report.json", tmp / "metrics.json"
        start = time.perf_counter()
        assert main(["diagnose", "--urdf", str(folder / "kuka_lwr4.urdf"), "--data", paths[0], "--validate", paths[1],
                     "--jobs", jobs, *options, "--out", str(report)]) == 0
        wall = time.perf_counter() - start
        assert main(["predict", "--model", str(report), "--data", paths[2], "--metrics", str(metrics)]) == 0
        mse = np.array(list(json.loads(metrics.read_text())["mse"].values()))
        effects = [f"{effect['spec']}@{'/'.join(effect['channels'])}" for effect in json.loads(report.read_text())["effects"]]
    print(f"KUKA {' '.join(options) or 'defaults'}: run 3 MSE per joint {' '.join(f'{value:.3g}' for value in mse)} total {mse.sum():.3f} N2m2; "
          f"{len(effects)} effects: {', '.join(effects)}; diagnose {wall:.1f} s", flush=True)


def emps(folder: Path, jobs: str) -> None:
    from dynamics.models import build_model
    from dynamics.robots import load_robot
    from estimation.datasets.shared import emps_measurements
    from estimation.diagnosis.search import diagnose

    train, validate = emps_measurements(folder, "estimation"), emps_measurements(folder, "validation")
    start = time.perf_counter()
    diagnosis = diagnose(build_model(load_robot("emps"), "internal", "viscous"), train, validate,
                         jobs=None if jobs == "auto" else int(jobs))
    wall = time.perf_counter() - start
    effects = [f"{effect.spec}@{'/'.join(effect.channels)}" for effect in diagnosis.effects]
    print(f"EMPS validation MSE (as recorded) {diagnosis.before.validation.mse['tau1']:.1f} -> "
          f"{diagnosis.after.validation.mse['tau1']:.1f} N2; effects: {', '.join(effects)}; diagnose {wall:.1f} s",
          flush=True)


if __name__ == "__main__":
    jobs = sys.argv[1] if len(sys.argv) > 1 else "1"
    emps(DATA / "emps", jobs)
    kuka(DATA / "kuka_lwr4", jobs, *sys.argv[2:])
